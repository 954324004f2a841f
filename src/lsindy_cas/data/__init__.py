"""Step 2 — the measurements: ``Trajectory`` (t, q, q̇, Q; validation, power, CSV/NPZ files) and
smoothing, noise estimation and derivatives of measured signals (``smoothing``)."""
from .trajectory import Trajectory, load_trajectories

__all__ = ["Trajectory", "load_trajectories"]
