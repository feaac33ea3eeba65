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
    import os

    from ..sweep._engine import max_jobs

    if args.jobs < 1 and args.jobs != -1:
        raise InputError(f"--jobs must be >= 1 (or -1 for all cores), got {args.jobs}")
    if args.jobs > max_jobs():
        raise InputError(
            f"--jobs {args.jobs} is more than the largest accepted here, {max_jobs()} (4 per core of this"
            f" machine's {os.cpu_count() or 1}; -1 is one per core): more workers only share the cores"
        )
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
    """The sweep engine's words in this command's options, around a
    ``sweep()`` call: a checkpoint that ``--resume`` refuses (written for
    another model, grid or options, or damaged) ends with how to start
    afresh; an interrupted sweep says "resume with --resume"; the engine's
    warning about damaged chunk files (recomputed) is one chatterlab warning
    line, not a raw Python warning."""
    import warnings

    from ..sweep._checkpoint import DAMAGED_FIX, CheckpointWarning
    from ..sweep._result import SweepInterrupted
    from ._common import WARNINGS

    shown = warnings.showwarning

    def show(message: Any, category: Any, *rest: Any, **kw: Any) -> None:
        if issubclass(category, CheckpointWarning):  # printed with the command's other warnings
            line = f"chatterlab: warning: {message}"
            if line not in WARNINGS:
                WARNINGS.append(line)  # even with --quiet: it says that work is redone
            return
        shown(message, category, *rest, **kw)

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always", CheckpointWarning)
            warnings.showwarning = show
            yield
    except SweepInterrupted as exc:
        text = str(exc).removeprefix("sweep interrupted: ")
        text = text.replace(
            "run again with resume=True (CLI: --resume)", "resume with --resume (the same command)"
        )
        raise SweepInterrupted(text, done=exc.done, total=exc.total, checkpoint=exc.checkpoint) from None
    except InputError as exc:
        ck = checkpoint(args)
        text = str(exc)
        if ck and text.endswith(DAMAGED_FIX):
            raise InputError(
                text.removesuffix(DAMAGED_FIX)
                + f"; the checkpoint is damaged and cannot be resumed: remove the"
                f" folder {ck!r} (its saved chunks are lost), or run without --resume (and another"
                " --checkpoint DIR)"
            ) from None
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


def engine_opts(args: argparse.Namespace) -> dict[str, Any]:
    """The ``sweep()`` keywords of the engine's options (:func:`sweep_opts`),
    with the checkpoint always kept by the engine: the command removes its
    default checkpoint itself, after its outputs are in place
    (:func:`drop_checkpoint_after`)."""
    return {**sweep_opts(args), "keep_checkpoint": True}


def drop_checkpoint_after(args: argparse.Namespace, outs: Any, res: Any) -> None:
    """Remove the checkpoint of a complete sweep ``res`` once the outputs are
    moved into place (``outs``: the command's
    ``CommandOutputs``) -- only the default ``OUT.ckpt`` (a ``--checkpoint DIR``
    is the user's; a partial run keeps it for a ``--resume`` that retries).
    Never before: a run killed between its last chunk and its files leaves
    the complete checkpoint, from which ``--resume`` writes the files
    without computing anything."""
    if res.status == "ok" and res.checkpoint is not None and not sweep_opts(args)["keep_checkpoint"]:
        outs.then(res.discard_checkpoint)
