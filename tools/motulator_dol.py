#!/usr/bin/env python3
"""Reference for the saturated plant: motulator's own Γ-model induction machine and stiff
mechanics (`motulator.drive.model.InductionMachine`, `MechanicalSystem`, their `rhs` and
`compute_outputs`), on motulator's 2.2-kW example machine with main-flux saturation
(examples/drive/current_vector/plot_2kw_im_sat_cvc.py: R_s 3.7 Ω, R_r 2.5 Ω, L_ℓ 23 mH,
L_s(ψ) = 0.34/(1 + (0.84·ψ)^7) H, 2 pole pairs, J 0.015 kg·m²), started direct on line
from an ideal 400 V 50 Hz source (phase peak √2·400/√3) against a constant 14.6 N·m load
(its nominal torque) from rest, 1 s, integrated by scipy's DOP853 at rtol 1e-10.

    python3.12 tools/motulator_dol.py [--write]

Runs `cargo run -p hil-sim -- run hil-sim/scenarios/dol-motulator-2kw-sat.toml` and prints
the RMS difference of i_α, i_β, speed and torque relative to each signal's peak (the
acceptance of the saturation issue: 0.5 %). With --write it also writes the reference
`plant/tests/data/motulator_dol_2kw_sat.csv`, against which the Rust test
`plant/tests/motulator_dol.rs` checks the plant in CI without Python.
Needs Python ≥ 3.12 and: pip install motulator==0.18.0 scipy.
"""
import csv
import math
import subprocess
import sys
import tempfile
from importlib.metadata import version
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from motulator.drive import model

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "hil-sim/scenarios/dol-motulator-2kw-sat.toml"
REFERENCE = ROOT / "plant/tests/data/motulator_dol_2kw_sat.csv"
# The acceptance: RMS difference within 0.5 % of each signal's peak.
REL_RMS_TOL = 5e-3
T_STOP_S = 1.0
SAMPLE_S = 5e-4
LOAD_NM = 14.6
U_PEAK_V = math.sqrt(2.0) * 400.0 / math.sqrt(3.0)
W_S = 2.0 * math.pi * 50.0


def L_s(psi: float) -> float:
    """The example's saturation model (Qu, Ranta, Hinkkanen, Luomi, IEEE TIA 2012)."""
    return 0.34 / (1.0 + (0.84 * psi) ** 7)


def motulator_dol() -> list[dict[str, float]]:
    par = model.InductionMachinePars(n_p=2, R_s=3.7, R_r=2.5, L_ell=0.023, L_s=L_s)
    machine = model.InductionMachine(par)
    mechanics = model.MechanicalSystem(J=0.015)
    mechanics.set_external_load_torque(LOAD_NM)

    def f(t, y):
        psi_s = complex(y[0], y[1])
        psi_r = complex(y[2], y[3])
        machine.state.psi_s_ab, machine.state.psi_r_ab = psi_s, psi_r
        machine.inp.u_s_ab = U_PEAK_V * complex(math.cos(W_S * t), math.sin(W_S * t))
        machine.inp.w_M = y[4]
        machine.set_outputs(t)
        mechanics.state.w_M = complex(y[4], 0.0)
        mechanics.inp.tau_M = machine.out.tau_M
        d_psi_s, d_psi_r = machine.rhs(t)
        _, d_w = mechanics.rhs(t)
        return [d_psi_s.real, d_psi_s.imag, d_psi_r.real, d_psi_r.imag, d_w.real]

    n = round(T_STOP_S / SAMPLE_S)
    t_eval = np.linspace(0.0, T_STOP_S, n + 1)
    sol = solve_ivp(f, (0.0, T_STOP_S), [0.0] * 5, method="DOP853", t_eval=t_eval, rtol=1e-10, atol=1e-12)
    assert sol.success, sol.message
    rows = []
    for k, t in enumerate(sol.t):
        y = sol.y[:, k]
        machine.state.psi_s_ab = complex(y[0], y[1])
        machine.state.psi_r_ab = complex(y[2], y[3])
        i_s, _, tau = machine.compute_outputs(machine.state, machine.inp)
        rows.append({"t_s": t, "i_alpha_a": i_s.real, "i_beta_a": i_s.imag, "omega_m_rad_s": y[4], "torque_nm": tau})
    return rows


def hil_sim_dol() -> list[dict[str, float]]:
    with tempfile.TemporaryDirectory() as out:
        subprocess.run(
            ["cargo", "run", "-q", "--release", "-p", "hil-sim", "--", "run", str(SCENARIO), "--out", out],
            cwd=ROOT, check=True, stdout=subprocess.DEVNULL,
        )
        with open(Path(out) / "trace.csv") as f:
            return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]


def main() -> int:
    ref = motulator_dol()
    if "--write" in sys.argv:
        REFERENCE.parent.mkdir(parents=True, exist_ok=True)
        with open(REFERENCE, "w", newline="") as f:
            f.write(f"# motulator {version('motulator')} InductionMachine + MechanicalSystem, scipy {version('scipy')} "
                    "DOP853 rtol 1e-10: written by tools/motulator_dol.py --write\n")
            w = csv.DictWriter(f, fieldnames=list(ref[0].keys()), lineterminator="\n")
            w.writeheader()
            for r in ref:
                w.writerow({k: f"{v:.9e}" for k, v in r.items()})
        print(f"wrote {REFERENCE.relative_to(ROOT)} ({len(ref)} rows)")
    sim = hil_sim_dol()
    by_t = {round(r["t_s"] / SAMPLE_S): r for r in sim}
    worst = 0.0
    for key, sim_key in [("i_alpha_a", "i_alpha_a"), ("i_beta_a", "i_beta_a"),
                         ("omega_m_rad_s", "omega_m_rad_s"), ("torque_nm", "torque_nm")]:
        pairs = [(r[key], by_t[round(r["t_s"] / SAMPLE_S)][sim_key]) for r in ref
                 if round(r["t_s"] / SAMPLE_S) in by_t]
        peak = max(abs(a) for a, _ in pairs)
        rms = math.sqrt(sum((a - b) ** 2 for a, b in pairs) / len(pairs))
        worst = max(worst, rms / peak)
        print(f"{key:>14}: peak {peak:10.4f}, RMS difference {rms:.3e} = {rms / peak:.2e} of peak "
              f"({len(pairs)} samples; hil-sim's trace.csv has 6 decimals)")
    ok = worst <= REL_RMS_TOL
    print(f"largest: {worst:.2e} of peak (tolerance {REL_RMS_TOL:.0e}): {'ok' if ok else 'FAILED'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
