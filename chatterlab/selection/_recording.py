"""A recording of the cut -- sound from a microphone, an accelerometer's
signal -- as (time, signal): a WAV file (scipy.io.wavfile: PCM or float,
one channel chosen) or a CSV file of ``time,signal`` columns (a header row
and ``#`` comment lines skipped).  Every problem is one
:class:`~chatterlab.errors.InputError` line naming the file and the fix."""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError

__all__ = ["read_recording", "MAX_SAMPLES"]

#: the most samples read (a 10-minute recording at 100 kHz): the spectrum costs n log n
MAX_SAMPLES = 60_000_000


def read_recording(path: str | os.PathLike[str], *, channel: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``(t, x)`` of a WAV or CSV recording: times (s, uniform from 0 for a
    WAV) and the signal (any unit) of channel ``channel`` (a WAV's channel,
    or the CSV's signal column after the time: 0 is the second column)."""
    p = Path(path)
    name = str(path)
    if isinstance(channel, bool) or not isinstance(channel, int | np.integer) or channel < 0:
        raise InputError(f"recording {name}: the channel must be a whole number >= 0 (got {channel!r})")
    if not p.exists():
        raise InputError(f"recording {name}: file not found; check the path")
    if p.is_dir():
        raise InputError(f"recording {name}: is a directory, not a recording")
    suffix = p.suffix.lower()
    if suffix == ".wav":
        return _wav(p, name, int(channel))
    if suffix in (".csv", ".txt"):
        return _csv(p, name, int(channel))
    raise InputError(
        f"recording {name}: give a .wav file or a .csv file of time,signal columns (got '{suffix}')"
    )


def _wav(p: Path, name: str, channel: int) -> tuple[np.ndarray, np.ndarray]:
    import warnings

    from scipy.io import wavfile

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", wavfile.WavFileWarning)  # unknown chunks (cue points, lists)
            rate, data = wavfile.read(str(p), mmap=False)
    except PermissionError:
        raise InputError(f"recording {name}: cannot be read (permission denied)") from None
    except (ValueError, EOFError, OSError, IndexError, TypeError) as exc:
        detail = str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
        raise InputError(
            f"recording {name}: not a readable WAV file ({detail}); write it as PCM or float WAV, or as a CSV"
            " of time,signal"
        ) from None
    data = np.asarray(data)
    if data.ndim == 1:
        data = data[:, None]
    if channel >= data.shape[1]:
        raise InputError(
            f"recording {name}: has {data.shape[1]} channel(s); channel {channel} does not exist (count from 0)"
        )
    if not rate > 0:
        raise InputError(f"recording {name}: the sample rate is {rate} Hz; it must be > 0")
    x = data[:, channel]
    if x.dtype == np.uint8:  # 8-bit PCM is unsigned, centred on 128
        x = x.astype(float) - 128.0
    x = x.astype(float)
    _check_samples(name, x)
    return np.arange(x.size) / float(rate), x


def _csv(p: Path, name: str, channel: int) -> tuple[np.ndarray, np.ndarray]:
    rows: list[tuple[float, float]] = []
    header = False
    col = channel + 1
    try:
        with open(p, newline="", encoding="utf-8") as fh:
            for k, row in enumerate(csv.reader(fh)):
                if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
                    continue
                try:
                    ti, xi = float(row[0]), float(row[col])
                except ValueError:
                    if rows or header:
                        raise InputError(
                            f"recording {name}: line {k + 1} is not two numbers ({','.join(row)[:60]!r});"
                            " a recording is time,signal rows after at most one header line"
                        ) from None
                    header = True  # one header line
                    continue
                except IndexError:
                    raise InputError(
                        f"recording {name}: line {k + 1} has {len(row)} column(s); column {col + 1} (the"
                        f" signal of channel {channel}) is missing"
                    ) from None
                rows.append((ti, xi))
                if len(rows) > MAX_SAMPLES:
                    raise InputError(
                        f"recording {name}: more than {MAX_SAMPLES} samples; shorten or decimate it"
                    )
    except UnicodeDecodeError:
        raise InputError(f"recording {name}: is not a text CSV file (time,signal rows)") from None
    except PermissionError:
        raise InputError(f"recording {name}: cannot be read (permission denied)") from None
    if len(rows) < 4:
        raise InputError(f"recording {name}: holds {len(rows)} time,signal rows; a spectrum needs many more")
    a = np.array(rows, float)
    t, x = a[:, 0], a[:, 1]
    if not np.all(np.isfinite(t)):
        raise InputError(f"recording {name}: a time is not finite (nan or inf)")
    dt = np.diff(t)
    step = (t[-1] - t[0]) / (t.size - 1)
    if not step > 0 or np.max(np.abs(dt - step)) > 1e-6 * step:
        raise InputError(
            f"recording {name}: the times must increase in equal steps (found steps from {dt.min():.3g} to"
            f" {dt.max():.3g} s); resample it uniformly"
        )
    _check_samples(name, x)
    return t, x


def _check_samples(name: str, x: np.ndarray) -> None:
    if x.size < 4:
        raise InputError(f"recording {name}: holds {x.size} samples; a spectrum needs many more")
    if x.size > MAX_SAMPLES:
        raise InputError(
            f"recording {name}: has {x.size} samples, more than {MAX_SAMPLES}; shorten or decimate it"
        )
    if not np.all(np.isfinite(x)):
        raise InputError(f"recording {name}: a sample is not finite (nan or inf)")
    if float(np.ptp(x)) == 0.0 or not math.isfinite(float(np.ptp(x))):
        raise InputError(f"recording {name}: the signal is constant: nothing was recorded")


def describe(recording: Any) -> str:
    """How a recording is named in messages and results."""
    return str(recording) if isinstance(recording, str | os.PathLike) else "the signal given"
