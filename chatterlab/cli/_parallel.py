"""The options of the commands that run on the sweep engine (``sweep`` and
``lobes --positions``): workers, backend, dask scheduler and TLS, checkpoint
and resume."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..io._files import Outputs


def parallel_args(p: argparse.ArgumentParser) -> None:
    """Add the sweep engine's options to a command's parser."""
    p.add_argument("--jobs", type=int, default=2, help="worker processes (default 2; -1: all cores)")
    p.add_argument("--backend", choices=["loky", "dask", "serial"], default="loky")
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="dask scheduler, e.g. tls://host:8786 (with --backend dask); it runs code as you: trust it",
    )
    p.add_argument("--tls-ca-file", metavar="PEM", help="CA certificate of a tls:// scheduler")
    p.add_argument("--tls-cert", metavar="PEM", help="client certificate for a tls:// scheduler")
    p.add_argument("--tls-key", metavar="PEM", help="client private key for a tls:// scheduler")
    p.add_argument(
        "--checkpoint", metavar="DIR", help="checkpoint directory (default: OUT.ckpt when --out is given)"
    )
    p.add_argument("--resume", action="store_true", help="resume an interrupted run from its checkpoint")


def sweep_opts(args: argparse.Namespace) -> dict[str, Any]:
    """The keyword arguments of ``sweep()`` that come from these options."""
    if args.jobs < 1 and args.jobs != -1:
        raise InputError(f"--jobs must be >= 1 (or -1 for all cores), got {args.jobs}")
    if args.scheduler and args.backend != "dask":
        raise InputError("--scheduler is for --backend dask")
    return {
        "security": security(args),
        "jobs": args.jobs,
        "backend": args.backend,
        "scheduler": args.scheduler,
        "progress": not args.quiet,
        # a complete run's results are in --out: the default checkpoint OUT.ckpt has done its job
        # (removed under its lock); a partial run keeps it; a --checkpoint DIR is the user's
        "keep_checkpoint": bool(args.checkpoint) or not args.out,
    }


def check_checkpoint(args: argparse.Namespace, outs: Outputs) -> None:
    """The checkpoint directory is neither an input nor an output file."""
    import os

    ck = checkpoint(args)
    if ck is None:
        return
    real = os.path.realpath(ck)
    for name, what in (
        (args.model, "the model file"),
        (args.out, "--out"),
        (getattr(args, "plot", None), "--plot"),
    ):
        if name and os.path.realpath(name) == real:
            raise InputError(f"--checkpoint {ck!r} is {what}; give the checkpoint its own directory")
    if Path(ck).exists() and not Path(ck).is_dir():
        raise InputError(f"--checkpoint {ck!r} exists and is not a directory")


#: the fingerprint entry of the model: its file text, --variant and --set
MODEL_KEY = "model (file, --variant, --set)"

#: the sweep engine's own way to continue, replaced by the command line's
_ENGINE_FIX = "; use another checkpoint directory or delete this one (resume only continues the same sweep)"


def fingerprint(model_hash: str, args: argparse.Namespace, options: tuple[str, ...]) -> dict[str, str]:
    """The checkpoint fingerprint of a command as a mapping ``option ->
    value``, so that a refused ``--resume`` names the option that changed.
    ``options`` are option strings (``"--terms"``); an option not given is
    left out (the refusal then says "unset")."""
    out = {MODEL_KEY: model_hash}
    for opt in options:
        value = getattr(args, opt.lstrip("-").replace("-", "_"))
        if value is not None:
            out[opt] = str(value)
    return out


@contextlib.contextmanager
def resume_refusal(args: argparse.Namespace) -> Iterator[None]:
    """A checkpoint that ``--resume`` refuses because it was written for
    another model, grid or options: its one line ends with how to start
    afresh in this command's options."""
    try:
        yield
    except InputError as exc:
        ck = checkpoint(args)
        text = str(exc)
        where = f"checkpoint directory {str(Path(ck))!r}" if ck else None
        if not (args.resume and where and text.startswith(where) and " written " in text):
            raise
        fix = (
            f"; to start afresh, run without --resume and give another --checkpoint DIR, or delete {ck!r}"
            " (and the partial results saved there)"
        )
        raise InputError(text.replace(_ENGINE_FIX, "") + fix) from None


def security(args: argparse.Namespace) -> Any:
    """dask TLS settings for a remote --scheduler tls://..., or None."""
    files = {"--tls-ca-file": args.tls_ca_file, "--tls-cert": args.tls_cert, "--tls-key": args.tls_key}
    given = {k: v for k, v in files.items() if v}
    tls = bool(args.scheduler) and str(args.scheduler).startswith("tls://")
    if not given and not tls:
        return None
    if given and not tls:
        raise InputError(f"{', '.join(given)} need --backend dask --scheduler tls://HOST:PORT")
    missing = [k for k, v in files.items() if not v]
    if missing:
        raise InputError(f"a tls:// scheduler needs {', '.join(files)}; missing {', '.join(missing)}")
    for k, v in files.items():
        if not Path(v).is_file():
            raise InputError(f"{k} {v!r}: no such file")
    try:
        from distributed.security import Security
    except ImportError:
        raise InputError("--backend dask needs dask.distributed: pip install chatterlab[dask]") from None
    return Security(
        tls_ca_file=args.tls_ca_file,
        tls_client_cert=args.tls_cert,
        tls_client_key=args.tls_key,
        require_encryption=True,
    )


def checkpoint(args: argparse.Namespace) -> str | None:
    """The checkpoint directory: --checkpoint DIR, else OUT.ckpt, else none."""
    if args.checkpoint:
        return args.checkpoint
    if args.out:
        return args.out + ".ckpt"
    if args.resume:
        raise InputError("--resume needs --out FILE (the checkpoint is FILE.ckpt) or --checkpoint DIR")
    return None
