"""One BLAS thread for chatterlab's many small dense problems.

The matrices are a few hundred wide at most: threaded OpenBLAS gains nothing
on them and, on shared cores, is 10x slower and erratic.  threadpoolctl
limits only the libraries loaded when the limit is entered, and scipy's
wheels carry their own OpenBLAS beside numpy's: scipy is loaded first, since
``import chatterlab`` does not load it (a limit entered before it missed it,
and the milling example took 60-120x longer).  Parallel work goes through
the sweep engine's worker processes, whose BLAS loky limits.
"""

from __future__ import annotations

from contextlib import AbstractContextManager
from typing import Any


def one_blas_thread(blas_only: bool = True) -> AbstractContextManager[Any]:
    """A context with every loaded BLAS (and, ``blas_only=False``, OpenMP)
    library limited to one thread, scipy's included."""
    import scipy.linalg  # noqa: F401  (loads scipy's OpenBLAS before the limit)
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas" if blas_only else None)
