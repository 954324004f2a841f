"""Output files: checked before the work starts, written atomically, readable like any other file.

* :func:`check_writable` — a file the command will write: its folder exists and is writable, and the
  name is not a folder.  Commands call it before any heavy work, so a typo never costs a fit.
* :func:`existing_dir` — a folder that must already exist and be writable.
* :func:`output_dir` — a folder the user named for several outputs: created if missing (that is
  what naming it asks for), but never its missing parents.
* :func:`atomic_write` — a file the user already has is replaced whole or not at all, and the new
  file gets the permissions of a normally created one (``0666`` less the umask), not the private
  mode of the temporary file it was written to.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Callable

__all__ = ["atomic_write", "check_writable", "existing_dir", "output_dir"]


def check_writable(path, what: str = "output file") -> Path:
    """Raise ``ValueError`` unless ``path`` can be created or replaced; returns it as a ``Path``."""
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise ValueError(f"{what} {path} is a directory; give a file name")
    if not parent.is_dir():
        raise ValueError(f"{what} {path}: directory {parent} does not exist (create it first)")
    if not os.access(parent, os.W_OK | os.X_OK) or not _can_create_in(parent):
        raise ValueError(f"{what} {path}: directory {parent} is not writable")
    if path.exists() and not os.access(path, os.W_OK):
        raise ValueError(f"{what} {path} exists and is not writable")
    return path


def existing_dir(path, what: str = "output directory") -> Path:
    """A folder that must already exist and be writable (nothing is created)."""
    path = Path(path)
    if not path.is_dir():
        raise ValueError(f"{what} {path}: no such directory (create it first)")
    return output_dir(path, what)


def output_dir(path, what: str = "output directory") -> Path:
    """Create the folder ``path`` if needed (not its parents) and check that it is writable."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{what} {path} exists and is not a directory")
    if not path.exists():
        check_writable(path, what)
        path.mkdir()
    if not os.access(path, os.W_OK | os.X_OK) or not _can_create_in(path):
        raise ValueError(f"{what} {path} is not writable")
    return path


def _can_create_in(folder: Path) -> bool:
    """Whether a file can really be created in ``folder`` (``os.access`` says yes to root on a
    read-only file system such as /sys)."""
    try:
        with tempfile.TemporaryFile(dir=folder):
            return True
    except OSError:
        return False


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(path, write: Callable[[str], None]) -> Path:
    """Call ``write(tmp_name)`` on a temporary file beside ``path``, then rename it onto ``path``.

    If ``write`` raises, ``path`` is untouched and the temporary file is removed.  The folder must
    exist (``ValueError`` otherwise: nothing is created that the user did not ask for).
    """
    path = check_writable(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=path.suffix)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path
