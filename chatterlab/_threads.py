"""One BLAS thread for chatterlab's many small dense problems.

The matrices are a few hundred wide at most: threaded OpenBLAS gains nothing
on them and, on shared cores, is 10x slower and erratic.  threadpoolctl
limits only the libraries loaded when the limit is entered, and scipy's
wheels carry their own OpenBLAS beside numpy's: scipy is loaded first, since
``import chatterlab`` does not load it (a limit entered before it missed it,
and the milling example took 60-120x longer).  Parallel work goes through
the sweep engine's worker processes, whose BLAS loky limits.

Finding the loaded libraries (threadpoolctl scans the process's shared
objects) costs ~2 ms, and a sweep or the lobe engine enters the limit once per
task: the controller that holds the libraries found is kept, and found again
only when a module has been imported since (a new extension module is how a
new BLAS arrives), so entering the limit costs ~15 us.
"""

from __future__ import annotations

import sys
from contextlib import AbstractContextManager
from typing import Any

#: (number of modules imported when it was made, the ThreadpoolController)
_CONTROLLER: list[Any] = [-1, None]


def _controller() -> Any:
    """The threadpoolctl controller of the loaded libraries, made again when
    a module was imported since the last one was made."""
    import scipy.linalg  # noqa: F401  (loads scipy's OpenBLAS before the limit)

    if _CONTROLLER[0] != len(sys.modules):
        from threadpoolctl import ThreadpoolController

        _CONTROLLER[1] = ThreadpoolController()
        _CONTROLLER[0] = len(sys.modules)
    return _CONTROLLER[1]


def one_blas_thread(blas_only: bool = True) -> AbstractContextManager[Any]:
    """A context with every loaded BLAS (and, ``blas_only=False``, OpenMP)
    library limited to one thread, scipy's included."""
    return _controller().limit(limits=1, user_api="blas" if blas_only else None)
