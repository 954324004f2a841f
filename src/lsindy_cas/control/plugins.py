"""System-specific policies behind a small interface, for :class:`~.controller.Controller`.

A plug-in is an object with ``build(model, task, controller) -> policy``; the policy has
``reset()`` and ``__call__(x) -> inputs`` (one per task input).  The controller validates the
task and the model as always, then hands the states to the policy; its :meth:`reached` stays the
task's goal test.

The plug-ins shipped with the package are the sub-packages of :mod:`lsindy_cas.control` that
define ``PLUGIN`` (a class whose instances are plug-ins; its ``name`` is the sub-package's):
:func:`available` lists them, :func:`plugin` builds one by name (the command line's
``--plugin NAME``).  Nothing in the generic core names one.
"""
from __future__ import annotations

import importlib
import pkgutil

__all__ = ["available", "plugin"]


def available() -> list:
    """Names of the shipped plug-ins (sub-packages of ``lsindy_cas.control`` with ``PLUGIN``)."""
    from . import __path__ as here
    return sorted(m.name for m in pkgutil.iter_modules(here) if m.ispkg and "PLUGIN" in
                  getattr(importlib.import_module(f"{__package__}.{m.name}"), "__all__", ()))


def plugin(name: str, **options):
    """The shipped plug-in ``name`` built with ``options``.

    Raises
    ------
    ValueError
        No shipped plug-in has that name (the message lists those there are).
    """
    names = available()
    if name not in names:
        raise ValueError(f"unknown plug-in {name!r}: known plug-ins are {', '.join(names)}")
    return importlib.import_module(f"{__package__}.{name}").PLUGIN(**options)
