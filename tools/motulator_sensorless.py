#!/usr/bin/env python3
"""Reference for the sensorless comparison (issue 53): motulator's own sensorless example,
examples/drive/current_vector/plot_2kw_im_sat_cvc.py of motulator 0.18 — its 2.2-kW
induction machine with main-flux saturation (Γ model: R_s 3.7 Ω, R_r 2.5 Ω, L_ℓ 23 mH,
L_s(ψ) = 0.34/(1 + (0.84·ψ)^7) H, 2 pole pairs, J 0.015 kg·m²) on a 540 V bus (ideal
converter, one sample of delay, no PWM), its sensorless current-vector control (the
reduced-order observer with speed adaptation on constant inverse-Γ estimates R_s 3.7 Ω,
R_R 2.1 Ω, L_σ 21 mH, L_M 224 mH; 125 µs sampling; speed PI at 2π·4 rad/s) — and its
manoeuvre: the speed reference 0 → 0.5 p.u. (78.54 rad/s) at 0.2 s, the nominal 14.6 N·m
load at 0.75 s, 1.5 s in all.

    python3.12 tools/motulator_sensorless.py [--write]

Prints motulator's speed-estimate RMS error over the run (the estimate at each sample
against the rotor's speed there). With --write it writes
`hil-sim/tests/data/motulator_sensorless_2kw.csv` (every 1 ms: t, the rotor's speed, the
estimate; the RMS error over every sample in its first line), against which the Rust test
`hil-sim/tests/motulator_sensorless.rs` holds this drive's own estimate on the same motor
and manoeuvre in CI without Python. Needs Python ≥ 3.12 and: pip install motulator==0.18.0.
"""
import math
import sys
from importlib.metadata import version
from pathlib import Path

import numpy as np
import motulator.drive.control.im as control
from motulator.drive import model, utils

ROOT = Path(__file__).resolve().parent.parent
REFERENCE = ROOT / "hil-sim/tests/data/motulator_sensorless_2kw.csv"
T_STOP_S = 1.5
SAMPLE_S = 1e-3


def L_s(psi: float) -> float:
    """The example's saturation model (Qu, Ranta, Hinkkanen, Luomi, IEEE TIA 2012)."""
    return 0.34 / (1.0 + (0.84 * psi) ** 7)


def simulate():
    nom = utils.NominalValues(U=400, I=5, f=50, P=2.2e3, tau=14.6)
    base = utils.BaseValues.from_nominal(nom, n_p=2)
    par = model.InductionMachinePars(n_p=2, R_s=3.7, R_r=2.5, L_ell=0.023, L_s=L_s)
    mdl = model.Drive(
        model.InductionMachine(par),
        model.MechanicalSystem(J=0.015),
        model.VoltageSourceConverter(u_dc=540),
        pwm=False,
        delay=1,
    )
    est_par = control.InductionMachineInvGammaPars(n_p=2, R_s=3.7, R_R=2.1, L_sgm=0.021, L_M=0.224)
    cfg = control.CurrentVectorControllerCfg(psi_s_nom=base.psi, i_s_max=1.5 * base.i, sensorless=True)
    ctrl = control.VectorControlSystem(
        control.CurrentVectorController(est_par, cfg),
        control.SpeedController(J=0.015, alpha_s=2 * math.pi * 4),
    )
    ctrl.set_speed_ref(lambda t: (t > 0.2) * 0.5 * base.w_M)
    mdl.mechanics.set_external_load_torque(lambda t: (t > 0.75) * nom.tau)
    return model.Simulation(mdl, ctrl).simulate(t_stop=T_STOP_S)


def main() -> int:
    write = "--write" in sys.argv[1:]
    res = simulate()
    t = np.asarray(res.ctrl.t)
    est = np.asarray(res.ctrl.fbk.w_M)
    actual = np.interp(t, np.asarray(res.mdl.t), np.asarray(res.mdl.mechanics.w_M))
    rms = float(np.sqrt(np.mean((est - actual) ** 2)))
    print(f"motulator {version('motulator')}: speed-estimate RMS error {rms:.4f} rad/s over {len(t)} samples")
    if write:
        grid = np.arange(0.0, T_STOP_S + 0.5 * SAMPLE_S, SAMPLE_S)
        with REFERENCE.open("w") as f:
            f.write(f"# rms_error_rad_s={rms:.6f} motulator={version('motulator')}\n")
            f.write("t_s,omega_m_rad_s,omega_est_rad_s\n")
            for k in grid:
                i = min(int(np.searchsorted(t, k)), len(t) - 1)
                f.write(f"{t[i]:.6f},{actual[i]:.6f},{est[i]:.6f}\n")
        print(f"wrote {REFERENCE.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
