#!/usr/bin/env python3
"""The design toolkit against python-control, same work, one run.

    python3 tools/control_bench.py [--rows N]

1. ICAD ω_r sweep: closed-loop poles of the full 2×2 stator-current loop (DeLorenzo
   eq. (13) motor, seed 002 controller (20) on both axes) at ω_r = 0, 5, …, 5000 rad/s.
   python-control: ss plant, tf→ss controller, append, feedback, poles.
2. 200×200 k_p–k_i grid on seed 000's interval current plant: robustly stable when the PI
   closes all 16 Kharitonov loops stably. python-control: feedback(C·G_ij, 1).poles() for
   each plant. The full grid (640 000 calls) takes minutes, so by default python-control
   computes every 20th k_p row (10 × 200 points) and its time is scaled by 20 — `--rows
   200` runs all of it.

Both tools' results are compared (abscissae within 1e-6 relative, grid verdicts equal) and
the run fails if they disagree. `design bench` (release build) provides the Rust side and
times each of its figures as the best of three; python-control's ω_r sweep is the best of
three after a warm-up, its grid one pass. Needs: pip install control.
"""
import argparse
import json
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import control
import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def rust_side() -> dict:
    subprocess.run(["cargo", "xtask", "build-tools"], cwd=ROOT, check=True)
    out = subprocess.run([str(ROOT / "target/release/design"), "bench"], cwd=ROOT, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out)


# The motor file is read once, outside the timed sweep.
MOTOR = tomllib.loads((ROOT / "motors/delorenzo-eq13.toml").read_text())["motor"]


def im_matrices(omega_r: float):
    """Seed 002 eq. (1), stationary frame, x = [i_α, i_β, ψ_α, ψ_β] (written out here, not
    taken from the Rust code)."""
    m = MOTOR
    rs, rr, ls, lr, lm = m["rs_ohm"], m["rr_ohm"], m["ls_h"], m["lr_h"], m["lm_h"]
    sigma = 1 - lm * lm / (ls * lr)
    sls, tr = sigma * ls, lr / rr
    a = rs / sls + lm * lm * rr / (sls * lr * lr)
    k = lm / (sls * lr)
    A = np.array([
        [-a, 0, k / tr, k * omega_r],
        [0, -a, -k * omega_r, k / tr],
        [lm / tr, 0, -1 / tr, -omega_r],
        [0, lm / tr, omega_r, -1 / tr],
    ])
    B = np.array([[1 / sls, 0], [0, 1 / sls], [0, 0], [0, 0]])
    C = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])
    return A, B, C


def icad_sweep(speeds) -> tuple[float, list[float]]:
    """Best of three timed sweeps after one warm-up speed (as `design bench` does)."""
    s = control.tf("s")
    k = 326.5 * (s + 400) ** 2 * (s + 1000) / (s * (s * s + 100 * s + 42500))
    kk = control.append(control.ss(k), control.ss(k))

    def sweep(ws):
        out = []
        for w in ws:
            A, B, C = im_matrices(w)
            plant = control.ss(A, B, C, np.zeros((2, 2)))
            loop = control.feedback(plant * kk, np.eye(2))
            out.append(float(np.max(loop.poles().real)))
        return out

    sweep(speeds[:1])
    best, out = float("inf"), []
    for _ in range(3):
        t0 = time.perf_counter()
        out = sweep(speeds)
        best = min(best, time.perf_counter() - t0)
    return best, out


def kharitonov(lo, hi):
    """The four Kharitonov polynomials (descending coefficients)."""
    pats = [(0, 0, 1, 1), (1, 1, 0, 0), (0, 1, 1, 0), (1, 0, 0, 1)]
    n = len(lo)
    return [[hi[i] if p[(n - 1 - i) % 4] else lo[i] for i in range(n)] for p in pats]


def grid(rows: list[int], kps, kis) -> tuple[float, dict[int, str]]:
    plant = tomllib.loads((ROOT / "design/plants/seed000-current.toml").read_text())
    nums = kharitonov(plant["numerator"]["lo"], plant["numerator"]["hi"])
    dens = kharitonov(plant["denominator"]["lo"], plant["denominator"]["hi"])
    plants = [control.tf(n, d) for n in nums for d in dens]
    t0 = time.perf_counter()
    out = {}
    for r in rows:
        verdicts = []
        for ki in kis:
            c = control.tf([kps[r], ki], [1, 0])
            ok = all(np.max(control.feedback(c * g, 1).poles().real) < 0 for g in plants)
            verdicts.append("1" if ok else "0")
        out[r] = "".join(verdicts)
    return time.perf_counter() - t0, out


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rows", type=int, default=10, help="k_p rows python-control computes (of 200)")
    args = ap.parse_args()
    ours = rust_side()
    speeds = [5.0 * i for i in range(ours["icad_sweep"]["speeds"])]
    py_sweep_s, py_abs = icad_sweep(speeds)
    rs_abs = ours["icad_sweep"]["abscissae"]
    worst = max(abs(a - b) / max(1.0, abs(b)) for a, b in zip(py_abs, rs_abs))
    g = ours["grid"]
    n = g["n"]
    kps = np.linspace(g["kp_range"][0], g["kp_range"][1], n)
    kis = np.linspace(g["ki_range"][0], g["ki_range"][1], n)
    step = max(1, n // max(1, min(args.rows, n)))
    rows = list(range(0, n, step))
    py_grid_s, py_rows = grid(rows, kps, kis)
    mismatches = sum(a != b for r in rows for a, b in zip(py_rows[r], g["rows_kp_major"][r]))
    scale = n / len(rows)
    print(f"ICAD ω_r sweep, {len(speeds)} speeds (2×2 loop, 12 states, eigenvalues):")
    print(f"  design {ours['icad_sweep']['seconds'] * 1e3:9.2f} ms   python-control {py_sweep_s * 1e3:9.1f} ms"
          f"   ratio {py_sweep_s / ours['icad_sweep']['seconds']:6.0f}×   (abscissae agree to {worst:.1e} rel.)")
    print(f"200×200 k_p–k_i grid × 16 Kharitonov plants ({n * n * 16} closed loops):")
    print(f"  design (poles) {g['seconds_poles']:7.3f} s   design (Routh) {g['seconds_routh']:7.3f} s")
    print(f"  python-control {py_grid_s * scale:7.1f} s" + ("" if scale == 1 else
          f" (measured {py_grid_s:.1f} s on {len(rows)} of {n} k_p rows, scaled by {scale:.0f})"))
    print(f"  ratio {py_grid_s * scale / g['seconds_poles']:6.0f}× (same pole computation), "
          f"{py_grid_s * scale / g['seconds_routh']:6.0f}× (Routh)   "
          f"verdicts differing on the compared rows: {mismatches}")
    return 0 if worst < 1e-6 and mismatches == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
