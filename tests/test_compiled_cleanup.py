"""The JIT (control/compiled.py) leaves no temporary files behind."""

import gc
import shutil
import tempfile

import casadi as ca
import numpy as np
import pytest

from lsindy_cas.control import compiled

needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler (gcc)")


def test_loaded_jit_libraries_are_removed_and_nothing_else(tmp_path):
    jit = tmp_path / "lsindy_jit_abc"
    jit.mkdir()
    lib = jit / "tmp_casadi_compiler_shellXy12.so"
    lib.write_bytes(b"")
    other = tmp_path / "other"
    other.mkdir()
    keep = [other / "tmp_casadi_compiler_shellQ.so", jit.parent / "libfoo.so"]
    for k in keep:
        k.write_bytes(b"")
    maps = tmp_path / "maps"
    again = tmp_path / "lsindy_jit_def" / "tmp_casadi_compiler_shellZz9.so"
    again.parent.mkdir()
    again.write_bytes(b"")  # written back by a second load; its first copy is still mapped
    maps.write_text("7f0000-7f1000 r-xp 00000000 08:01 1234    " + str(lib) + "\n"
                    "7f4000-7f5000 r-xp 00000000 08:01 77    " + str(again) + " (deleted)\n"
                    "7f1000-7f2000 rw-p 00000000 00:00 0 \n"            # anonymous: no path
                    "7f2000-7f3000 r-xp 00000000 08:01 99   [vdso]\n"
                    + "".join(f"7f3000-7f4000 r-xp 00000000 08:01 5 {k}\n" for k in keep))
    assert compiled._remove_loaded_libraries(str(maps)) == [lib, again]
    assert not jit.exists() and not again.parent.exists()  # the emptied folders go too
    assert all(k.exists() for k in keep)
    assert compiled._remove_loaded_libraries(str(tmp_path / "no-maps")) == []


def _small_solver():
    x = ca.SX.sym("x", 2)
    nlp = {"x": x, "p": ca.SX.sym("p", 0, 1), "f": (x[0] - 1) ** 2 + ca.sin(x[1]) ** 2,
           "g": x[0] + x[1]}
    return compiled.compiled_nlpsol("s_cleanup", "ipopt", nlp, {
        "print_time": False, "ipopt": {"print_level": 0, "sb": "yes"}})


@needs_gcc
@pytest.mark.parametrize("cache", ["on", "off"])
def test_compiling_and_loading_leave_no_temporary_files(tmp_path, monkeypatch, capfd, cache):
    """Nothing is left in the working or the temporary folder, and CasADi does not warn
    ("Failed to remove ...jit_tmp*.c") when a loaded Function is freed: the empty C file that
    loading writes stays in the load folder (the cache's ``jit-load``; cache off: one
    ``lsindy_jit_load_*`` folder per process, removed at exit if empty) until CasADi removes it."""
    scratch, cwd = tmp_path / "tmp", tmp_path / "cwd"
    scratch.mkdir()
    cwd.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    monkeypatch.setattr(compiled, "_LOAD_TMP", None)
    monkeypatch.setenv("LSINDY_CACHE_DIR", str(tmp_path / "cache") if cache == "on" else "off")
    monkeypatch.chdir(cwd)
    x = ca.SX.sym("x", 2)
    f = ca.Function("f_cleanup", [x], [ca.sin(x[0]) * x[1]])

    def loading_leftovers():
        """Files in the load folder (empty C files while a loaded Function lives)."""
        folders = ([tmp_path / "cache" / "jit-load"] if cache == "on"
                   else list(scratch.glob("lsindy_jit_load_*")))
        files = [p for d in folders for p in d.iterdir()]
        assert all(p.name.startswith("jit_tmp") and p.stat().st_size == 0 for p in files)
        return files

    for _ in range(2):                      # compiled, then (cache on) loaded from the cache
        g = compiled.compiled_function(f)
        np.testing.assert_allclose(float(g([0.3, -1.2])), np.sin(0.3) * -1.2, rtol=1e-14)
        solver = _small_solver()
        assert float(solver(x0=[0.0, 0.0], lbg=0.0, ubg=2.0)["x"][0]) == pytest.approx(1.0)
        assert [p.name for p in scratch.iterdir()
                if not p.name.startswith("lsindy_jit_load_")] == []
        assert list(cwd.iterdir()) == []        # also while it lives: a process may exit
        loading_leftovers()
        del g, solver
        gc.collect()
        assert list(cwd.iterdir()) == []
        assert loading_leftovers() == []        # CasADi removed its files itself
    assert "Failed to remove" not in capfd.readouterr().err
    assert len(compiled.cached_files()) == (2 if cache == "on" else 0)
    if cache == "off":
        for folder in scratch.glob("lsindy_jit_load_*"):
            compiled._remove_if_empty(folder)   # what runs at exit
    assert list(scratch.iterdir()) == []


def test_load_folder_sweeps_files_left_by_functions_alive_at_exit(tmp_path, monkeypatch):
    """A Function alive at a process's exit is never freed, so CasADi never removes its empty
    jit_tmp*.c: the next load removes such files once older than a day, nothing else."""
    import os
    import time

    monkeypatch.setenv("LSINDY_CACHE_DIR", str(tmp_path))
    load = tmp_path / "jit-load"
    load.mkdir()
    old, fresh, kept = load / "jit_tmpOld123.c", load / "jit_tmpNew456.c", load / "jit_tmpBig.c"
    for p in (old, fresh):
        p.write_bytes(b"")
    kept.write_text("int x;")  # not an empty placeholder: not ours to remove
    stale = time.time() - compiled.STALE_SECONDS - 60
    os.utime(old, (stale, stale))
    os.utime(kept, (stale, stale))
    assert compiled._load_dir() == load
    assert not old.exists() and fresh.exists() and kept.exists()
