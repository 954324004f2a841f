"""Figures of the swing-up experiment: the analogue of the paper's Fig. 5.

(a) cart phase portrait (x, x_dot) and (b) pole phase portrait (theta, theta_dot) of the
training data and the controlled trajectories; (c) applied force and (d) pole angle against time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["swingup_figure"]


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _angle(theta, upright):
    """Pole angle shifted so that upright is pi and hanging is 0 or 2 pi (range [0, 2 pi)),
    with NaN inserted where it wraps so that plotted lines do not jump across the axes."""
    a = np.mod(np.asarray(theta, dtype=float) - upright + np.pi, 2 * np.pi)
    a[1:][np.abs(np.diff(a)) > np.pi] = np.nan
    return a


def swingup_figure(training, runs, ctrl, out):
    """Write the Fig. 5 analogue as PNG files and return their paths.

    Parameters
    ----------
    training : list of Trajectory
        Identification data (may be empty).
    runs : dict of str -> list of Episode
        Closed-loop episodes per scenario (:func:`lsindy_cas.paper.swingup.run_episode`).
    ctrl : SwingUpMPC
        The controller (for the upright angle, the force set and the track limit).
    out : Path
        Output directory (created).

    Returns
    -------
    list of Path
        ``swingup_phase.png`` (panels a, b) and ``swingup_time.png`` (panels c, d).
    """
    plt = _pyplot()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    episodes = runs.get("nominal") or next(iter(runs.values()), [])
    cart_name, pole_name = ctrl.coords[ctrl.cart_index], ctrl.coords[ctrl.pole_index]
    up = ctrl.upright
    cart, pole = (episodes[0].coords.index(cart_name), episodes[0].coords.index(pole_name)) \
        if episodes else (ctrl.cart_index, ctrl.pole_index)

    fig, (ax_c, ax_p) = plt.subplots(1, 2, figsize=(11, 4.4))
    for ep in episodes:
        ax_c.plot(ep.X[:, cart], ep.X[:, 2 + cart], color="tab:blue", lw=0.6, alpha=0.5)
        ax_p.plot(_angle(ep.X[:, pole], up), ep.X[:, 2 + pole], color="tab:blue", lw=0.6,
                  alpha=0.5)
    for i, tr in enumerate(training):
        label = "training data" if i == 0 else None
        jc, jp = tr.coords.index(cart_name), tr.coords.index(pole_name)
        ax_c.plot(tr.q[:, jc], tr.qd[:, jc], color="k", lw=2, label=label)
        ax_p.plot(_angle(tr.q[:, jp], up), tr.qd[:, jp], color="k", lw=2, label=label)
    ax_c.plot([], [], color="tab:blue", label=f"MPC, {len(episodes)} random starts")
    for x in (-ctrl.track_limit, ctrl.track_limit):
        ax_c.axvline(x, color="tab:red", ls="--", lw=1)
    ax_p.axvline(np.pi, color="tab:green", ls=":", lw=1, label="upright")
    ax_c.set(xlabel="cart position x (m)", ylabel="cart velocity (m/s)",
             title="(a) cart phase portrait")
    ax_p.set(xlabel="pole angle from hanging (rad)", ylabel="pole rate (rad/s)",
             title="(b) pendulum phase portrait", xlim=(0, 2 * np.pi))
    ax_c.legend(loc="upper left", fontsize=8)
    ax_p.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    phase = out / "swingup_phase.png"
    fig.savefig(phase, dpi=120)
    plt.close(fig)

    fig, (ax_u, ax_a) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    if episodes:
        ep = episodes[0]
        t_ctrl = np.arange(ep.forces.size) * ctrl.dt
        ax_u.step(t_ctrl, ep.forces, where="post", color="tab:blue", lw=1)
        ax_u.set_yticks(ctrl.levels)
        for e in episodes:
            ax_a.plot(e.t, _angle(e.X[:, pole], up), lw=0.7, alpha=0.6)
    ax_a.axhline(np.pi, color="k", ls=":", lw=1)
    ax_a.axhspan(np.pi - 0.1, np.pi + 0.1, color="tab:green", alpha=0.15,
                 label="success band ±0.1 rad")
    ax_u.set(ylabel="force (N)", title="(c) applied force, first episode")
    ax_a.set(xlabel="time (s)", ylabel="pole angle from hanging (rad)",
             title="(d) pole angle, all episodes", ylim=(0, 2 * np.pi))
    ax_a.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    timing = out / "swingup_time.png"
    fig.savefig(timing, dpi=120)
    plt.close(fig)
    return [phase, timing]
