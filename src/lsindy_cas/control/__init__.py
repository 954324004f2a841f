"""Step 5 — control with the identified equations.

The generic core, for any model and any task (nothing in it names a coordinate or a system):

``task`` (what the user wants: :class:`Task`) → ``system`` (the model under the task's inputs) →
``local`` (the stabiliser from the model's linearisation at the target) → ``search`` (beam
search over the input levels into the goal region, guided by the identified energy) →
``controller`` (:class:`Controller`, one object from model + task) → ``episodes`` (closed-loop
runs and the goal's bookkeeping).  The relaxed multiple-shooting MPC (``ocp`` → ``staged`` /
``shooting`` → ``mpc``, compiled by ``compiled``) turns its relaxed input into levels by
``rounding`` or ``lookahead``; ``correction`` and ``coefficients`` adapt its predictions online.

``plugins`` holds system-specific policies behind a small interface; the shipped ones are the
sub-packages that define ``PLUGIN``, kept apart from this core.

Rule: nothing here imports :mod:`lsindy_cas.identify`; a controller takes any object with an
``ode()`` (tests check it by reading the imports)."""

__all__ = ["Task", "Controller", "ControllerSettings"]


def __getattr__(name):                      # lazy: importing a submodule loads no CasADi here
    if name == "Task":
        from .task import Task
        return Task
    if name in ("Controller", "ControllerSettings"):
        from . import controller
        return getattr(controller, name)
    raise AttributeError(name)
