"""A disk cache of a library's CasADi Functions (Θ, Γ, ∇Θ, ∂Θ/∂q̇, ∂²Θ/∂q̇²).

Building them converts every term from sympy to SX and differentiates the whole library (about
0.04 s for the spherical pendulum's 125 terms, in a command that takes about a second); they depend
only on the terms, so a library seen before loads them instead (CasADi's own serialisation).

Safety: the key hashes everything the Functions depend on — the cache format, the versions of
lsindy_cas, CasADi and sympy, the coordinate names and every term's name (a name is the term's
sympy string, which determines the expression); a file is written whole or not at all
(:func:`lsindy_cas._io.atomic_write`); and the cache never breaks a run: a missing, unreadable,
corrupt or mismatched file is rebuilt, and a read-only, full or missing cache directory only means
nothing is saved.

Where: ``$LSINDY_CACHE_DIR`` if set (``off`` or an empty value disables the cache), else
``$XDG_CACHE_HOME/lsindy_cas`` or ``~/.cache/lsindy_cas``.  Files are small (about 0.3 MB for 125
terms) and may be deleted at any time.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import casadi as ca

__all__ = ["cache_dir", "load", "save"]

FORMAT = 1                 # bump when the set of Functions or their definition changes
_NAMES = ("theta", "gamma", "grad", "dqd", "hess")


def cache_dir() -> Path | None:
    """The cache folder, or None when the cache is switched off (``LSINDY_CACHE_DIR=off``)."""
    env = os.environ.get("LSINDY_CACHE_DIR")
    if env is not None:
        return None if env.strip() in ("", "off") else Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "lsindy_cas"


def _key(coords, names) -> str:
    import sympy

    from .._version import __version__
    text = json.dumps([FORMAT, __version__, ca.__version__, sympy.__version__, list(coords),
                       list(names)])
    return hashlib.sha256(text.encode()).hexdigest()


def _path(coords, names) -> Path | None:
    folder = cache_dir()
    return None if folder is None else folder / f"library-{_key(coords, names)[:32]}.json"


def load(coords, names, check) -> dict | None:
    """The cached Functions of the library (coords, names), or None when absent or unusable.

    ``check(functions) -> bool`` validates what was read (shapes); anything else — a missing or
    unreadable file, a bad format, a hash collision, a CasADi deserialisation error — is a miss.
    """
    path = _path(coords, names)
    if path is None:
        return None
    try:
        data = json.loads(path.read_text())
        if data.get("key") != _key(coords, names) or sorted(data["functions"]) != sorted(_NAMES):
            return None
        funcs = {name: ca.Function.deserialize(data["functions"][name]) for name in _NAMES}
    except Exception:              # noqa: BLE001 - a cache must never break a run: rebuild
        return None
    return funcs if check(funcs) else None


def save(coords, names, functions: dict) -> None:
    """Write the Functions for (coords, names); any failure is ignored (nothing cached)."""
    path = _path(coords, names)
    if path is None:
        return
    try:
        from .._io import atomic_write
        text = json.dumps({"key": _key(coords, names),
                           "functions": {name: functions[name].serialize() for name in _NAMES}})
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda tmp: Path(tmp).write_text(text))
    except Exception:              # noqa: BLE001 - read-only or full disk, ...: run uncached
        return
