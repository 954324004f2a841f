"""Step 5 — control with the identified equations.

The generic core, for any model and any task (nothing in it names a coordinate or a system):

``task`` (what the user wants: :class:`Task`) → ``system`` (the model under the task's inputs) →
``local`` (the stabiliser from the model's linearisation at the target) → ``search`` (beam
search over the input levels into the goal region, guided by the identified energy) →
``controller`` (:class:`Controller`, one object from model + task) → ``episodes`` (closed-loop
runs and the goal's bookkeeping).  ``plugins`` holds system-specific policies behind a small
interface.

The cart-pendulum swing-up (``cart_pendulum.SwingUpMPC``, the ``cart_pendulum`` plug-in) is built
on the relaxed multiple-shooting MPC of ``ocp``/``shooting``/``mpc`` with its force-choice rules
(``rounding``, ``lookahead``), balancers and guards.

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
