"""Convert the MultiArm-Pendulum rig's single-pendulum free-swing data to trajectory CSVs.

Source: github dynamicslab/MultiArm-Pendulum, ParameterEstimation/SinglePendulum (MIT licence,
``LICENSE`` beside this script), file ``SinglePendulumDataForParameterEstimation.mat``: 4
identification pieces (``Time_id``, ``Y_id``) and 2 validation pieces (``Time_vad``, ``Y_vad``) of
one free swing, sampled at 1 kHz; ``Y`` rows are θ (rad, from the upward vertical: hanging is
θ = π) and θ̇ (rad/s).

Every 10th sample is kept (1 kHz -> 100 Hz): the swing is at ~1.3 Hz with no content near 50 Hz
(the rates were already denoised by the authors), so nothing aliases, the files are 10x smaller,
and 100 Hz is the rate of the paper's experiments.  Times are the recording's own (the pieces
follow each other).  The authors' grey-box parameters are written to ``authors_fit.json``.

Run:  python examples/data/real_pendulum/convert.py MAT_DIR [--every 10]
"""
import argparse
import json
from pathlib import Path

import numpy as np
import scipy.io

HERE = Path(__file__).resolve().parent
NAMES = ["a1", "m1", "I1", "k1", "g"]


def convert(mat_dir, out_dir=HERE, every: int = 10) -> list:
    """Write ``id1..id4.csv``, ``val1.csv``, ``val2.csv`` and ``authors_fit.json``; return the paths."""
    mat_dir, out_dir = Path(mat_dir), Path(out_dir)
    if not isinstance(every, int) or every < 1:
        raise ValueError(f"every must be a positive integer, got {every!r}")
    data = scipy.io.loadmat(mat_dir / "SinglePendulumDataForParameterEstimation.mat", squeeze_me=True)
    written = []
    for key, prefix in [("id", "id"), ("vad", "val")]:
        for i, (t, Y) in enumerate(zip(data["Time_" + key], data["Y_" + key]), start=1):
            t, Y = np.asarray(t, float)[::every], np.asarray(Y, float)[:, ::every]
            path = out_dir / f"{prefix}{i}.csv"
            np.savetxt(path, np.column_stack([t, Y[0], Y[1]]), delimiter=",", fmt="%.10g",
                       header="t,theta,theta_dot", comments="")
            written.append(path)
    fit = scipy.io.loadmat(mat_dir / "EstimatedParameters_SinglePendulum.mat", squeeze_me=True)
    params = dict(zip(NAMES, np.asarray(fit["EstimatedParameters"], float).tolist()))
    path = out_dir / "authors_fit.json"
    path.write_text(json.dumps({
        "model": "(m1*a1**2 + I1)*theta_ddot = m1*a1*g*sin(theta) - k1*theta_dot",
        "units": {"a1": "m", "m1": "kg", "I1": "kg m^2", "k1": "N m s", "g": "m/s^2"},
        "parameters": params}, indent=2) + "\n")
    return written + [path]


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mat_dir", help="folder holding the two .mat files")
    parser.add_argument("--every", type=int, default=10, help="keep every N-th sample (default 10)")
    args = parser.parse_args()
    for p in convert(args.mat_dir, every=args.every):
        print(p)
