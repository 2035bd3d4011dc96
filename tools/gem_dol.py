#!/usr/bin/env python3
"""Independent cross-check of the hil-sim plant: a direct-on-line start computed by
gym-electric-motor's squirrel-cage induction-motor equations (GEM's own `electrical_ode`
and `torque`) integrated with scipy's DOP853 at rtol = 1e-11, against the trace hil-sim
writes for the same scenario file.

    python3 tools/gem_dol.py [hil-sim/scenarios/dol-delorenzo.toml]

Runs `hil-sim run SCENARIO --out DIR` itself (the release build `cargo xtask build-tools`
makes), prints the largest differences and exits non-zero when they exceed the stated
tolerances. Needs: pip install gym-electric-motor scipy.
"""
import csv
import math
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from gym_electric_motor.physical_systems.electric_motors import SquirrelCageInductionMotor

ROOT = Path(__file__).resolve().parent.parent
# Tolerances relative to the peak of each signal. hil-sim's RK4 at 10 µs is converged to
# ~1e-11 A (its step study), CSV output carries 6 decimals: 1e-5 of the peak is the bound.
REL_TOL = 1e-5


def main() -> int:
    scenario = Path(sys.argv[1] if len(sys.argv) > 1 else ROOT / "hil-sim/scenarios/dol-delorenzo.toml")
    sc = tomllib.loads(scenario.read_text())
    m, src = sc["motor"], sc["source"]
    load = sc.get("load", {"torque_nm": 0.0})["torque_nm"]
    assert src["kind"] == "sine"

    with tempfile.TemporaryDirectory() as out:
        subprocess.run(["cargo", "xtask", "build-tools"], cwd=ROOT, check=True)
        subprocess.run(
            [str(ROOT / "target/release/hil-sim"), "run", str(scenario), "--out", out],
            cwd=ROOT, check=True, stdout=subprocess.DEVNULL,
        )
        with open(Path(out) / "trace.csv") as f:
            rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]

    motor = SquirrelCageInductionMotor(motor_parameter=dict(
        p=m["pole_pairs"], l_m=m["lm_h"], l_sigs=m["ls_h"] - m["lm_h"], l_sigr=m["lr_h"] - m["lm_h"],
        j_rotor=m["j_kgm2"], r_s=m["rs_ohm"], r_r=m["rr_ohm"],
    ))
    amp, w_e = src["amplitude_v"], 2 * math.pi * src["frequency_hz"]
    j, b = m["j_kgm2"], m["b_nms"]

    def rhs(t, x):
        # x = [i_sα, i_sβ, ψ_rα, ψ_rβ, ε, ω_m, θ_m]; GEM's ε is the electrical angle.
        # The SCIM class adds the zero rotor voltages itself.
        u = np.array([amp * math.cos(w_e * t), amp * math.sin(w_e * t)])
        d_el = motor.electrical_ode(x[:5], u, x[5])
        torque = motor.torque(x[:5])
        return np.concatenate([d_el, [(torque - b * x[5] - load) / j, x[5]]])

    t_eval = np.array([r["t_s"] for r in rows])
    t0 = time.perf_counter()
    sol = solve_ivp(rhs, (0.0, t_eval[-1]), np.zeros(7), method="DOP853", t_eval=t_eval, rtol=1e-11, atol=1e-12)
    wall = time.perf_counter() - t0
    if not sol.success:
        print("scipy failed:", sol.message)
        return 2

    torque_gem = np.array([motor.torque(sol.y[:5, k]) for k in range(sol.y.shape[1])])
    checks = [
        ("i_alpha_a", sol.y[0]), ("i_beta_a", sol.y[1]), ("psi_alpha_wb", sol.y[2]),
        ("psi_beta_wb", sol.y[3]), ("omega_m_rad_s", sol.y[5]), ("torque_nm", torque_gem),
    ]
    ok = True
    print(f"{scenario.name}: {len(rows)} samples over {t_eval[-1]:.3f} s; GEM + scipy DOP853 (rtol 1e-11) took {wall:.1f} s")
    print(f"{'signal':<15} {'peak':>12} {'max |Δ|':>12} {'relative':>10}")
    for name, ref in checks:
        sim = np.array([r[name] for r in rows])
        peak = float(np.max(np.abs(ref)))
        diff = float(np.max(np.abs(sim - ref)))
        rel = diff / peak if peak > 0 else diff
        ok &= rel <= REL_TOL
        print(f"{name:<15} {peak:12.6f} {diff:12.3e} {rel:10.2e}")
    print("agreement within", REL_TOL, "of each peak:", "yes" if ok else "NO")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
