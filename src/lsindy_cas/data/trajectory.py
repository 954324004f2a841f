"""Trajectory data: one continuous run of a mechanical system, with validation and file I/O.

File format (DESIGN.md): CSV with a header row or NPZ with the same keys — ``t`` (s, strictly
increasing, not necessarily evenly spaced), one column per coordinate ``<q>``, one ``<q>_dot`` per
coordinate, optional ``Q_<q>`` (applied generalized force; missing = 0) and optional ``<q>_ddot``
(exact accelerations).  Positions only: without any ``<q>_dot`` column the velocities are estimated
from the positions (:func:`lsindy_cas.data.velocities.estimate_velocities`) and the trajectory says
so (``velocities == "estimated"``); a file must have all ``<q>_dot`` columns or none.
"""
from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._io import atomic_write

__all__ = ["Trajectory", "load_trajectories", "as_trajectories"]

MIN_SAMPLES = 5


def _as_matrix(a, n_rows: int, n_cols: int, what: str) -> np.ndarray:
    try:
        a = np.asarray(a, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{what} must be numeric") from None
    if a.ndim == 1 and n_cols == 1:
        a = a[:, None]
    if a.shape != (n_rows, n_cols):
        raise ValueError(f"{what} must have shape ({n_rows}, {n_cols}) (n_samples, n_coords), "
                         f"got {a.shape}")
    if not np.all(np.isfinite(a)):
        bad = int(np.argwhere(~np.isfinite(a))[0][0])
        raise ValueError(f"{what} contains NaN or inf (first at sample {bad})")
    return a


@dataclass
class Trajectory:
    """One continuous run: time, positions, velocities, applied forces.

    Parameters
    ----------
    t : array (n_samples,)
        Time in seconds, strictly increasing.
    q : array (n_samples, n_coords)
        Generalized coordinates.
    qd : array (n_samples, n_coords) or None
        Generalized velocities; None: estimated from ``q`` (positions only, see
        :meth:`from_positions`).
    coords : list of str
        Coordinate names (column order of ``q``).
    Q : array (n_samples, n_coords), optional
        Applied (non-conservative) generalized forces; zeros if omitted.
    qdd : array (n_samples, n_coords), optional
        Exact accelerations, when the source knows them (simulators); enables the derivative form.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    coords: list
    Q: np.ndarray | None = None
    qdd: np.ndarray | None = None
    source: str = "<memory>"
    #: "measured" (given) or "estimated" (from the positions)
    velocities: str = field(init=False, default="measured")
    #: estimated velocities: std of each estimate's error, (n_samples, n_coords); else None
    qd_error: np.ndarray | None = field(init=False, default=None, repr=False)

    @classmethod
    def from_positions(cls, t, q, coords, Q=None, source: str = "<memory>") -> "Trajectory":
        """A run measured by positions only (encoders, motion capture): velocities estimated.

        Same as ``Trajectory(t, q, None, coords, Q)``: q̇ is the derivative of the smoothed
        positions (:func:`lsindy_cas.data.velocities.estimate_velocities`), ``velocities`` is
        ``"estimated"`` and ``qd_error`` holds each estimate's error std, which the fit carries
        into its noise model.  ``ValueError`` if the run is too short or the positions too coarse.
        """
        return cls(t, q, None, coords, Q=Q, source=source)

    def __post_init__(self):
        if isinstance(self.coords, str):
            self.coords = [c.strip() for c in self.coords.split(",")]
        self.coords = list(self.coords)
        n = len(self.coords)
        if n == 0:
            raise ValueError(f"{self.source}: a trajectory needs at least one coordinate")
        try:
            t = np.asarray(self.t, dtype=float).ravel()
        except (TypeError, ValueError):
            raise TypeError(f"{self.source}: t must be numeric") from None
        if len(t) < MIN_SAMPLES:
            raise ValueError(f"{self.source}: too few samples ({len(t)}); need at least {MIN_SAMPLES}")
        if not np.all(np.isfinite(t)):
            raise ValueError(f"{self.source}: t contains NaN or inf")
        if np.any(np.diff(t) <= 0):
            i = int(np.argmax(np.diff(t) <= 0))
            raise ValueError(f"{self.source}: t must be strictly increasing "
                             f"(t[{i + 1}] = {t[i + 1]} after t[{i}] = {t[i]})")
        self.t = t
        N = len(t)
        self.q = _as_matrix(self.q, N, n, f"{self.source}: q")
        self.Q = np.zeros((N, n)) if self.Q is None else _as_matrix(self.Q, N, n, f"{self.source}: Q")
        if self.qd is None:
            from .velocities import estimate_velocities
            est = estimate_velocities(t, self.q, self.Q, source=self.source)
            self.qd, self.qd_error, self.velocities = est.qd, est.qd_error, "estimated"
        self.qd = _as_matrix(self.qd, N, n, f"{self.source}: q_dot")
        if self.qdd is not None:
            self.qdd = _as_matrix(self.qdd, N, n, f"{self.source}: q_ddot")

    # ------------------------------------------------------------------ derived
    @property
    def n_samples(self) -> int:
        return len(self.t)

    @property
    def X(self) -> np.ndarray:
        """States [q, q̇]: (n_samples, 2 n_coords)."""
        return np.hstack([self.q, self.qd])

    @property
    def Xdot(self) -> np.ndarray:
        """State derivatives [q̇, q̈] (needs exact accelerations ``qdd``)."""
        if self.qdd is None:
            raise ValueError(f"{self.source}: no accelerations; the derivative form needs q_ddot "
                             "columns (use the integral form instead)")
        return np.hstack([self.qd, self.qdd])

    @property
    def power(self) -> np.ndarray:
        """Power fed into the system P = Σ_i Q_i q̇_i: (n_samples,) in W."""
        return np.einsum("ij,ij->i", self.Q, self.qd)

    @property
    def actuated(self) -> list:
        """Coordinates with a non-zero applied force somewhere in the run."""
        return [c for c, col in zip(self.coords, self.Q.T) if np.any(col != 0)]

    def reorder(self, coords) -> "Trajectory":
        """The same run with columns in the order of ``coords`` (``ValueError`` if names differ)."""
        coords = list(coords)
        if sorted(coords) != sorted(self.coords):
            raise ValueError(f"{self.source}: trajectory coordinates {self.coords} do not match "
                             f"the library's {coords}")
        idx = [self.coords.index(c) for c in coords]
        out = Trajectory(self.t, self.q[:, idx], self.qd[:, idx], coords, self.Q[:, idx],
                         None if self.qdd is None else self.qdd[:, idx], self.source)
        out.velocities = self.velocities
        out.qd_error = None if self.qd_error is None else self.qd_error[:, idx]
        return out

    # ------------------------------------------------------------------ I/O
    def columns(self) -> dict:
        cols = {"t": self.t}
        for i, c in enumerate(self.coords):
            cols[c] = self.q[:, i]
        if self.velocities == "measured":     # estimated ones are re-estimated on loading
            for i, c in enumerate(self.coords):
                cols[c + "_dot"] = self.qd[:, i]
        for i, c in enumerate(self.coords):
            cols["Q_" + c] = self.Q[:, i]
        if self.qdd is not None:
            for i, c in enumerate(self.coords):
                cols[c + "_ddot"] = self.qdd[:, i]
        return cols

    def save(self, path) -> Path:
        """Write CSV or NPZ (by extension); atomic, so an existing file is never left half-written."""
        path = Path(path)
        cols = self.columns()
        suffix = path.suffix.lower()
        if suffix not in (".csv", ".npz"):
            raise ValueError(f"{path}: unknown trajectory format {suffix!r}; use .csv or .npz")
        def write(tmp):
            if suffix == ".csv":
                data = np.column_stack(list(cols.values()))
                np.savetxt(tmp, data, delimiter=",", header=",".join(cols), comments="", fmt="%.17g")
            else:
                np.savez(tmp, **cols)

        atomic_write(path, write)
        return path

    @classmethod
    def load(cls, path, coords=None) -> "Trajectory":
        """Read a CSV/NPZ trajectory; ``coords`` (names) picks and orders the coordinates.

        Without ``coords`` the coordinates are the columns that have a matching ``<q>_dot`` (a
        file without any ``<q>_dot`` column: every column but ``t``, ``Q_<q>``, ``<q>_ddot``).
        Without ``<q>_dot`` columns the velocities are estimated (:meth:`from_positions`).
        """
        path = Path(path)
        src = str(path)
        if not path.is_file():
            raise ValueError(f"{src}: no such file")
        cols = read_columns(path)
        if "t" not in cols:
            raise ValueError(f"{src}: missing column 't'")
        positions_only = not any(k.endswith("_dot") and not k.endswith("_ddot") for k in cols)
        if coords is None:
            coords = [k for k in cols if k != "t" and not k.startswith("Q_")
                      and not k.endswith(("_dot", "_ddot")) and (positions_only or k + "_dot" in cols)]
            if not coords:
                raise ValueError(f"{src}: no coordinate columns (need '<q>' and '<q>_dot' pairs)")
        coords = [coords] if isinstance(coords, str) else list(coords)
        others = [k for k in cols if k != "t" and k not in coords and k + "_dot" in cols]
        if others:
            raise ValueError(f"{src}: the file also has coordinate(s) {', '.join(others)} (with "
                             f"{', '.join(o + '_dot' for o in others)}), not among the coordinates "
                             f"named ({', '.join(coords)}); an unmodelled coordinate's motion "
                             f"carries energy, so name every coordinate (e.g. --coords "
                             f"{','.join(coords + others)}) or drop those columns from the file")
        have = [c for c in coords if c + "_dot" in cols]
        if have and len(have) < len(coords):
            lack = [c + "_dot" for c in coords if c + "_dot" not in cols]
            raise ValueError(f"{src}: has {', '.join(c + '_dot' for c in have)} but not "
                             f"{', '.join(lack)}; give every velocity column or none (positions "
                             f"only: velocities are then estimated from the positions)")
        for c in coords:
            for need in (c,) if positions_only else (c, c + "_dot"):
                if need not in cols:
                    raise ValueError(f"{src}: missing column {need!r} for coordinate {c!r} "
                                     f"(columns: {', '.join(cols)})")

        zeros = np.zeros(len(cols["t"]))

        def stack(fmt, missing_is_zero=False):
            names = [fmt.format(c) for c in coords]
            if not missing_is_zero and not all(n in cols for n in names):
                return None
            return np.column_stack([cols.get(n, zeros) for n in names])

        return cls(cols["t"], stack("{}"), None if positions_only else stack("{}_dot"), coords,
                   Q=stack("Q_{}", missing_is_zero=True), qdd=stack("{}_ddot"), source=src)


def read_columns(path: Path) -> dict:
    src = str(path)
    if path.suffix.lower() == ".npz":
        try:
            with np.load(path, allow_pickle=False) as z:
                cols = {k: np.asarray(z[k]) for k in z.files}
        except (OSError, ValueError) as exc:
            raise ValueError(f"{src}: not a readable NPZ file ({exc})") from None
    else:
        try:
            with open(path, encoding="utf-8") as fh:
                header = fh.readline().strip()
            names = [h.strip() for h in header.split(",")]
            if not header or any(not h for h in names):
                raise ValueError("bad header row")
            with warnings.catch_warnings():       # an empty file is reported below, not warned
                warnings.simplefilter("ignore", UserWarning)
                data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        except (OSError, ValueError, UnicodeDecodeError) as exc:
            raise ValueError(f"{src}: not a readable CSV trajectory ({exc})") from None
        if data.size == 0:
            raise ValueError(f"{src}: no data rows below the header")
        if data.shape[1] != len(names):
            raise ValueError(f"{src}: header has {len(names)} columns but rows have {data.shape[1]}")
        if len(set(names)) != len(names):
            raise ValueError(f"{src}: duplicate column names in header")
        cols = {n: data[:, i] for i, n in enumerate(names)}
    lengths = {k: v.shape[0] if v.ndim else 0 for k, v in cols.items()}
    if len(set(lengths.values())) > 1:
        raise ValueError(f"{src}: columns have mismatched lengths {lengths}")
    return cols


def load_trajectories(paths, coords=None) -> list:
    """Load several trajectory files (each one continuous run)."""
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    if not paths:
        raise ValueError("no trajectory files given")
    return [Trajectory.load(p, coords) for p in paths]


def as_trajectories(trajectories, coords, what="trajectories") -> list:
    """``trajectories`` (one Trajectory or an iterable of them) as a list, each reordered to
    ``coords``; TypeError/ValueError naming ``what`` otherwise."""
    if isinstance(trajectories, Trajectory):
        trajectories = [trajectories]
    try:
        trajectories = list(trajectories)
    except TypeError:
        raise TypeError(f"{what} must be a Trajectory or a list of them") from None
    if not trajectories:
        raise ValueError(f"{what} is empty")
    for tr in trajectories:
        if not isinstance(tr, Trajectory):
            raise TypeError(f"{what} must contain Trajectory objects, got {type(tr).__name__}")
    return [tr.reorder(coords) for tr in trajectories]
