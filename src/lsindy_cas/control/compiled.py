"""Compiled NLP functions for the MPC's solvers (``jit``, on by default where gcc is), cached.

CasADi evaluates the expanded SX functions of an NLP in its virtual machine at about 10 ns per
instruction; the swing-up's Hessian of the Lagrangian (40 RK4 intervals) has about 125,000, so
one evaluation costs about 1 ms, most of an interior-point iteration.  Compiled to C (the system
compiler at ``-O1``) they run several times faster: fatrop's iteration on the swing-up OCP went
from 1.5 to 0.36 ms when compiled (CPU time, loaded machine).  What is compiled is generated
from the staged NLP (:mod:`~lsindy_cas.control.staged`: the derivatives loop over one
interval's code), so the first build of a model compiles in about 8 s (compiling the expanded
NLP instead took 35-60 s).  The compiled code is kept on disk: the controller's solvers
(fatrop, IPOPT: the whole solver with its binary embedded, CasADi's serialisation) or
functions (the SQP's Hessian and Jacobian, handed to ``sqpmethod`` as ``hess_lag``/``jac_fg``)
are stored under a key hashing everything they depend on (the NLP's own serialisation, the
solver and its options, the versions of lsindy_cas and CasADi), so a controller built before
for the same model and options loads in about a second.

:func:`resolve_jit` chooses for ``jit=None`` (the controllers' default): compiled when gcc is
on the PATH, unless ``$LSINDY_JIT`` says otherwise (``0``/``off``: never, ``1``/``on``: always,
an error without gcc); without gcc and without the variable the controller runs uncompiled,
with one warning per process.

The folder is that of :mod:`lsindy_cas.symbolic.fcache` (``$LSINDY_CACHE_DIR``; ``off`` disables
the cache, and then every build compiles).  A missing, unreadable or corrupt file is rebuilt, and
an unwritable folder only means nothing is saved.  Files take about 5 MB per model and options
(the SQP's Hessian and Jacobian, fatrop with its NLP) and may be deleted at any time.  Nothing
is left in the temporary folder: CasADi's C sources and libraries are
removed once loaded (otherwise a ``/tmp/lsindy_jit_*`` folder, often with a 2 MB
library, would stay behind per compile and per load).  Loading also writes an empty ``jit_tmp*.c``
that CasADi removes when the Function is freed; it goes to the cache folder's ``jit-load``
(cache off: a per-process ``lsindy_jit_load_*`` folder, removed at exit if every Function was
freed by then, else left empty).  A Function still alive at exit is never freed, so its file
stays: empty files older than a day are swept from ``jit-load`` at the next load."""

from __future__ import annotations

import atexit
import contextlib
import hashlib
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

import casadi as ca

from .._io import atomic_write
from ..symbolic.fcache import cache_dir

__all__ = ["JIT_ENV", "CompileError", "check_compiler", "compiled_function", "compiled_nlpsol",
           "resolve_jit"]

FORMAT = 4  # bump when what is compiled, or how, changes
FLAGS = ["-O1"]  # -O0 compiled in 38 s but ran at 0.9 ms per fatrop iteration, -O1: 57 s, 0.36


def check_compiler():
    """Raise ValueError unless a C compiler (``gcc``, which CasADi's ``shell`` JIT calls) is on
    the PATH."""
    if shutil.which("gcc") is None:
        raise ValueError("jit=True needs a C compiler (gcc) on the PATH; install one or pass "
                         f"jit=False (or set {JIT_ENV}=0).")


class CompileError(RuntimeError):
    """The C compiler failed on the generated code (the controller then runs uncompiled)."""


def _compile(build):
    """``build()``, with CasADi's error for a failed compilation as :class:`CompileError`."""
    try:
        return build()
    except RuntimeError as exc:
        text = str(exc)
        if "Compilation failed" not in text:
            raise
        tried = text[text.find("Tried"):].splitlines()[0] if "Tried" in text else ""
        raise CompileError(f"the C compiler failed on the controller's generated code "
                           f"({tried or 'see its message above'})") from None


#: environment variable with the default of ``jit=None`` (see :func:`resolve_jit`)
JIT_ENV = "LSINDY_JIT"
_ENV_VALUES = {"0": False, "off": False, "false": False, "no": False,
               "1": True, "on": True, "true": True, "yes": True}
_warned_no_compiler = False


def resolve_jit(jit):
    """Whether a controller compiles its NLP: ``jit`` if True or False; for None (the default)
    ``$LSINDY_JIT`` if set (``0``/``off``/``false``/``no`` or ``1``/``on``/``true``/``yes``),
    else whether gcc is on the PATH (without it: False, and one ``RuntimeWarning`` per process).
    ValueError for any other value, or for compiling without gcc when asked to."""
    global _warned_no_compiler
    if jit is None:
        env = os.environ.get(JIT_ENV)
        if env is not None:
            if env.strip().lower() not in _ENV_VALUES:
                raise ValueError(f"${JIT_ENV} must be 0/off or 1/on (or unset: compiled where "
                                 f"gcc is), got {env!r}.")
            jit = _ENV_VALUES[env.strip().lower()]
        elif shutil.which("gcc") is None:
            if not _warned_no_compiler:
                import warnings
                warnings.warn("no C compiler (gcc) on the PATH: the controller's NLP runs "
                              f"uncompiled (step p99 about 1.6 times longer); install gcc, or "
                              f"set {JIT_ENV}=0 to choose this without the warning.",
                              RuntimeWarning, stacklevel=3)
                _warned_no_compiler = True
            return False
        else:
            jit = True
    if jit not in (False, True):
        raise ValueError(f"jit must be one of (None, False, True), got {jit!r}")
    if jit:
        check_compiler()
    return bool(jit)


def _jit_options():
    return {"jit": True, "compiler": "shell", "jit_serialize": "embed",
            "jit_options": {"flags": list(FLAGS), "verbose": False}}


@contextlib.contextmanager
def _scratch():
    """Run inside a new folder under the system's temporary one (its path is yielded): CasADi's
    JIT writes its C source and library into the current directory, and removes them when the
    Function is freed."""
    cwd = os.getcwd()
    folder = tempfile.mkdtemp(prefix="lsindy_jit_")
    os.chdir(folder)
    try:
        yield folder
    finally:
        os.chdir(cwd)


def _remove_loaded_libraries(maps="/proc/self/maps"):
    """Remove the JIT libraries this process has loaded from folders named ``lsindy_jit_*``.

    Loading a compiled Function from the cache makes CasADi write its embedded library back to
    the path it was built at (a folder under the temporary one) and load it from there, and
    nothing removes that file.  Once loaded it is no longer needed (POSIX keeps the mapping),
    so it is removed here, with its folder if that is left empty.  Without ``/proc`` (not
    Linux) nothing is done.  Returns the files removed.
    """
    try:
        with open(maps) as fh:
            fields = [line.split(None, 5) for line in fh]
    except OSError:
        return []
    # a library loaded again from the cache is written back to the same path, and the loader
    # reuses the mapping of the first (removed) copy, listed as "PATH (deleted)": the new copy
    # at PATH is then not mapped by anyone and goes too
    paths = {f[5].strip().removesuffix(" (deleted)") for f in fields if len(f) == 6}
    removed = []
    for path in sorted(paths):
        p = Path(path)
        if not (p.name.startswith("tmp_casadi_compiler_shell") and p.suffix == ".so"
                and p.parent.name.startswith("lsindy_jit_")):
            continue
        try:
            p.unlink()
            removed.append(p)
        except OSError:
            continue
        with contextlib.suppress(OSError):
            p.parent.rmdir()  # only if empty
    return removed


def _path(kind, parts):
    """Cache file for ``kind`` and the JSON-able ``parts`` (None when the cache is off)."""
    folder = cache_dir()
    if folder is None:
        return None
    from .._version import __version__
    text = json.dumps([FORMAT, __version__, ca.__version__, FLAGS, kind, *parts])
    return folder / f"jit-{kind}-{hashlib.sha256(text.encode()).hexdigest()[:32]}.casadi"


_LOAD_TMP = None  # the load folder when the cache is off (one per process)


def _load_dir():
    """Folder that compiled Functions are loaded in: ``jit-load`` in the cache folder, or (cache
    off or unwritable) one folder per process under the temporary one.

    Loading a compiled solver writes an empty ``jit_tmp*.c`` into the current directory, and
    CasADi removes it when the Function is freed -- with a warning on stderr if it is already
    gone (``lsindy swingup --jit`` printed two at exit while the load folder was deleted right
    after loading).  So the file stays where CasADi expects it until then.
    """
    global _LOAD_TMP
    folder = cache_dir()
    if folder is not None:
        with contextlib.suppress(OSError):
            load = Path(folder) / "jit-load"
            load.mkdir(parents=True, exist_ok=True)
            _sweep(load)
            return load
    if _LOAD_TMP is None or not _LOAD_TMP.is_dir():
        _LOAD_TMP = Path(tempfile.mkdtemp(prefix="lsindy_jit_load_"))
        atexit.register(_remove_if_empty, _LOAD_TMP)  # empty if every Function was freed
    return _LOAD_TMP


#: age (s) after which an empty ``jit_tmp*.c`` in the load folder is taken as left behind: a
#: Function still alive at a process's exit is never freed, so CasADi never removes its file
STALE_SECONDS = 86400.0


def _sweep(folder):
    """Remove the empty ``jit_tmp*.c`` files in ``folder`` older than :data:`STALE_SECONDS`
    (one per ``--jit`` run was left by a Function alive at exit)."""
    now = time.time()
    for p in folder.glob("jit_tmp*.c"):
        with contextlib.suppress(OSError):
            st = p.stat()
            if st.st_size == 0 and now - st.st_mtime > STALE_SECONDS:
                p.unlink()


def _remove_if_empty(folder):
    with contextlib.suppress(OSError):
        folder.rmdir()


def _load(path):
    """The Function stored at ``path`` (None if it cannot be read), its library file removed."""
    cwd = os.getcwd()
    os.chdir(_load_dir())  # CasADi's empty jit_tmp*.c goes there (see _load_dir)
    try:
        f = ca.Function.load(str(path))
    except Exception:  # noqa: BLE001 - a cache must never break a run: rebuild
        f = None
    finally:
        os.chdir(cwd)
    if f is None:
        return None
    _remove_loaded_libraries()
    return f


def _load_or_build(path, build):
    """The Function stored at ``path``, or ``build()`` (then stored there).  No temporary file
    is left behind: a built Function is saved (to the scratch folder when uncached:
    ``$LSINDY_CACHE_DIR=off`` or an unwritable folder), freed (CasADi removes the files it
    wrote) and loaded back, its library file then removed (:func:`_remove_loaded_libraries`)."""
    if path is not None and path.exists():
        f = _load(path)
        if f is not None:
            return f
    with _scratch() as folder:  # saved inside: the embedded library is read from the folder
        try:
            f = _compile(build)
        except CompileError:
            shutil.rmtree(folder, ignore_errors=True)
            raise
        target = None
        for where in (path, Path(folder) / "function.casadi"):
            if where is None:
                continue
            try:
                where.parent.mkdir(parents=True, exist_ok=True)
                atomic_write(where, lambda tmp: f.save(str(tmp)))
                target = where
                break
            except Exception:  # noqa: BLE001 - read-only or full disk: run uncached
                continue
    if target is not None:
        del f  # CasADi removes the source and library it wrote
        f = _load(target)
    if f is None:  # pragma: no cover - the file just written did not load back
        with _scratch():
            f = _compile(build)
    shutil.rmtree(folder, ignore_errors=True)
    return f


def compiled_function(f):
    """A compiled copy of the SX or MX function ``f`` (same inputs, outputs and names; an MX
    graph keeps its structure, e.g. a mapped function is compiled once, in a loop)."""
    def build():
        args = f.mx_in() if f.is_a("MXFunction") else f.sx_in()
        return ca.Function(f.name(), args, f.call(args), f.name_in(), f.name_out(),
                           _jit_options())
    return _load_or_build(_path("function", [f.serialize()]), build)


def compiled_nlpsol(name, plugin, nlp, opts):
    """``casadi.nlpsol(name, plugin, nlp, opts)`` with its NLP functions compiled.

    Parameters
    ----------
    name, plugin : str
    nlp : dict
        ``{"x", "p", "f", "g"}`` SX expressions.
    opts : dict
        Solver options (JSON-able apart from CasADi Functions, which must not be given here).
    """
    fg = ca.Function("nlp", [nlp["x"], nlp["p"]], [nlp["f"], nlp["g"]])
    parts = [name, plugin, json.dumps(opts, sort_keys=True), fg.serialize()]
    return _load_or_build(_path("nlpsol", parts),
                          lambda: ca.nlpsol(name, plugin, nlp, dict(opts, **_jit_options())))


def cached_files():
    """The compiled files in the cache folder (for tests and cleaning up)."""
    folder = cache_dir()
    return sorted(Path(folder).glob("jit-*.casadi")) if folder is not None else []
