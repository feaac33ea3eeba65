"""python -m chatterlab.cli: the chatterlab command."""

from ._main import main

raise SystemExit(main())
