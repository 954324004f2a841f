"""The pinned versions make uses (constraints.txt) satisfy pyproject.toml's bounds, and every
direct dependency is pinned, so a fresh machine installs what the suite was run with."""
import re
from pathlib import Path

import pytest

packaging = pytest.importorskip("packaging", reason="packaging reads version specifiers")
from packaging.requirements import Requirement  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _pins():
    pins = {}
    for line in (ROOT / "constraints.txt").read_text().splitlines():
        line = line.split("#")[0].strip()
        if line:
            name, version = line.split("==")
            pins[re.sub(r"[-_.]+", "-", name).lower()] = version
    return pins


def _requirements():
    try:
        import tomllib
    except ModuleNotFoundError:                      # Python 3.10
        tomllib = pytest.importorskip("tomli")
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = list(project["dependencies"])
    for extra in project["optional-dependencies"].values():
        reqs += extra
    return [Requirement(r) for r in reqs]


def test_every_dependency_is_pinned_inside_its_bounds():
    pins = _pins()
    for req in _requirements():
        if req.marker is not None and not req.marker.evaluate():
            continue                                 # e.g. tomli on Python >= 3.11
        name = re.sub(r"[-_.]+", "-", req.name).lower()
        assert name in pins, f"{req.name} is not pinned in constraints.txt"
        assert req.specifier.contains(pins[name], prereleases=True), (req, pins[name])
        assert req.specifier, f"{req.name} has no version bounds in pyproject.toml"
        assert any(s.operator in ("<", "<=", "~=", "==") for s in req.specifier), (
            f"{req.name} has no upper bound in pyproject.toml")
