"""A disk cache of what a library is made of: its CasADi Functions (Θ, Γ, ∇Θ, ∂Θ/∂q̇, ∂²Θ/∂q̇²)
and the term names of a polynomial library.

Building the Functions converts every term from sympy to SX and differentiates the whole library
(about 0.04 s for the spherical pendulum's 125 terms, in a command that takes about a second), and
forming a polynomial library's products in sympy about as long again; both depend only on the
library's definition, not on data, so a library seen before loads them instead (CasADi's own
serialisation; the names as text, each term parsed from its name only when it is used).

The same store keeps the per-term templates of :mod:`.template` (velocity degrees, positions,
expanded Euler-Lagrange rows) as JSON records, so that a library seen before needs no sympy at all.

Safety: the key hashes everything the Functions depend on — the cache format, the versions of
lsindy_cas, CasADi and sympy (sympy's read from its ``release.py``, without importing it), the
coordinate names and every term's name (a name is the term's
sympy string, which determines the expression); a file is written whole or not at all
(:func:`lsindy_cas._io.atomic_write`); and the cache never breaks a run: a missing, unreadable,
corrupt or mismatched file is rebuilt, and a read-only, full or missing cache directory only means
nothing is saved.

Where: ``$LSINDY_CACHE_DIR`` if set (``off`` or an empty value disables the cache), else
``$XDG_CACHE_HOME/lsindy_cas`` or ``~/.cache/lsindy_cas``.  Files are small (about 0.3 MB for 125
terms) and may be deleted at any time.
"""
from __future__ import annotations

import functools
import hashlib
import json
import os
import re
from pathlib import Path

import casadi as ca

__all__ = ["cache_dir", "load", "save", "read", "write"]

FORMAT = 1                 # bump when the set of Functions or their definition changes
_NAMES = ("theta", "gamma", "grad", "dqd", "hess")


def cache_dir() -> Path | None:
    """The cache folder, or None when the cache is switched off (``LSINDY_CACHE_DIR=off``)."""
    env = os.environ.get("LSINDY_CACHE_DIR")
    if env is not None:
        return None if env.strip() in ("", "off") else Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "lsindy_cas"


def _key(*parts) -> str:
    from .._version import __version__
    text = json.dumps([FORMAT, __version__, ca.__version__, sympy_version(), *parts])
    return hashlib.sha256(text.encode()).hexdigest()


_RELEASE = re.compile(r"""^__version__\s*=\s*["']([^"']+)["']""", re.M)


@functools.lru_cache(maxsize=None)
def sympy_version() -> str:
    """The installed sympy's version, without importing sympy (~0.5 s): from the module when it
    is already imported, else from its ``release.py`` (importlib.metadata itself costs ~0.1 s),
    else from the package metadata."""
    import sys
    if "sympy" in sys.modules:
        return str(sys.modules["sympy"].__version__)
    try:
        import importlib.util
        spec = importlib.util.find_spec("sympy")
        text = (Path(spec.origin).parent / "release.py").read_text()
        return _RELEASE.search(text).group(1)
    except Exception:              # noqa: BLE001 - a layout without release.py: ask the metadata
        from importlib.metadata import version
        return version("sympy")


def read(kind: str, parts: list) -> dict | None:
    """The JSON record ``kind`` stored for ``parts`` (JSON-able), or None (absent, unreadable,
    corrupt, switched off, or written for other parts)."""
    folder = cache_dir()
    if folder is None:
        return None
    key = _key(kind, *parts)
    try:
        data = json.loads((folder / f"{kind}-{key[:32]}.json").read_text())
    except Exception:              # noqa: BLE001 - a cache must never break a run: rebuild
        return None
    return data if isinstance(data, dict) and data.get("key") == key else None


def write(kind: str, parts: list, payload: dict) -> None:
    """Store ``payload`` (JSON-able) as record ``kind`` for ``parts``; any failure is ignored."""
    folder = cache_dir()
    if folder is None:
        return
    key = _key(kind, *parts)
    try:
        from .._io import atomic_write
        text = json.dumps({"key": key, **payload})
        folder.mkdir(parents=True, exist_ok=True)
        atomic_write(folder / f"{kind}-{key[:32]}.json", lambda tmp: Path(tmp).write_text(text))
    except Exception:              # noqa: BLE001 - read-only or full disk, ...: run uncached
        return


def load(coords, names, check) -> dict | None:
    """The cached Functions of the library (coords, names), or None when absent or unusable.

    ``check(functions) -> bool`` validates what was read (shapes); anything else — a missing or
    unreadable file, a bad format, a hash collision, a CasADi deserialisation error — is a miss.
    """
    data = read("library", [list(coords), list(names)])
    if data is None:
        return None
    try:
        if sorted(data["functions"]) != sorted(_NAMES):
            return None
        funcs = {name: ca.Function.deserialize(data["functions"][name]) for name in _NAMES}
    except Exception:              # noqa: BLE001 - a cache must never break a run: rebuild
        return None
    return funcs if check(funcs) else None


def save(coords, names, functions: dict) -> None:
    """Write the Functions for (coords, names); any failure is ignored (nothing cached)."""
    try:
        payload = {"functions": {name: functions[name].serialize() for name in _NAMES}}
    except Exception:              # noqa: BLE001
        return
    write("library", [list(coords), list(names)], payload)
