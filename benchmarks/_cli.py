"""Argument handling the benchmark scripts share."""

from __future__ import annotations

from pathlib import Path

__all__ = ["out_folder"]


def out_folder(ap, path, option="--out"):
    """The output folder ``path``, created with its parents if missing; if it cannot be, the
    parser's one-line error (exit 2) before any work starts."""
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        ap.error(f"{option} {out}: {e.strerror}")
    return out
