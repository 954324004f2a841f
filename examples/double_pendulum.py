"""Double pendulum (paper Sec. III-B) from *passive* data: a conserved quantity, then its scale.

Without any actuation the energy balance is Γ ξ = 0, which fixes the energy only up to a factor
(KRONIC's situation); a 0.1 s push on the first link (paper eq. 8) fixes the factor.  The
identified Lagrangian is printed trig-simplified — θ̇₁θ̇₂(cos θ₁ cos θ₂ + sin θ₁ sin θ₂) reads
θ̇₁θ̇₂ cos(θ₁ − θ₂) — as text and as LaTeX, and the equations of motion are checked by
extrapolating beyond the training window (the chaotic motion makes this a demanding test).

Run:  python examples/double_pendulum.py
"""
import numpy as np

from lsindy_cas import LagrangianSINDy, Library, printing, systems


def main(t_end=3.0, t_check=6.0, verbose=True):
    """Train on ``t_end`` s of free motion; compare simulations over ``t_check`` s.

    Returns
    -------
    LagrangianSINDy
        The identified model (``.terms()`` gives H's terms).
    """
    system = systems.double_pendulum()
    free = system.simulate(t_end=t_end, u=0.0)               # passive: no energy fed in
    push = system.simulate(t_end=0.1, u=1.0)                 # scale trial: 1 N·m on link 1

    library = Library.polynomial(
        system.coords, ["cos(theta1)", "cos(theta2)", "sin(theta1)", "sin(theta2)",
                        "theta1_dot", "theta2_dot"], degree=4)
    prior = ["theta1_dot**2", "cos(theta1)", "theta2_dot**2", "cos(theta2)"]
    model = LagrangianSINDy(library, n_terms=6, prior=prior).fit(free, scale_trajectories=push)
    if verbose:
        print(printing.describe(model, digits=4))
        print("\nLaTeX:\n" + printing.describe(model, digits=4, style="latex"))

    t = np.arange(int(round(t_check / 0.01)) + 1) * 0.01
    truth = system.simulate(t_end=t_check, u=0.0)
    X = model.simulate(system.x0, t)
    error = float(np.max(np.abs(X[:, :2] - truth.q)))
    if verbose:
        print(f"\nmax angle error after {t_check:g} s (trained on {t_end:g} s): {error:.1e} rad")
    # 1e-4 rad: the coefficients are accurate to ~1e-12, but the motion is chaotic, so errors
    # grow by orders of magnitude per second; 1e-4 still means "on top of the true curve"
    assert error < 1e-4, error
    return model


if __name__ == "__main__":
    main()
