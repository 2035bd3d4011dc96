#!/usr/bin/env python3
"""Simulation speed, measured in one run: hil-sim's scenario 2 (`speed-step`: IFOC + ICAD
speed step at a 20 kHz control rate, 3.5 s) against gym-electric-motor stepping the same
motor (DeLorenzo DL10115A1, 310 V supply) at the same 50 µs step.

    python3 tools/gem_speed.py [GEM_SECONDS]

GEM runs its `Cont-CC-SCIM-v0` environment with an open-loop V/f voltage (20 Hz, 30 % of
the bus) and no controller computed in Python, so its figure is an upper bound of GEM's
speed on scenario 2 and the printed ratio a lower bound of hil-sim's advantage. hil-sim's
figure is `hil-sim bench speed-step` (release build): the median simulated-seconds-per-wall-
second of 20 runs of the simulation loop after a warm-up run (the ratio's basis; the best
run is printed too: on a shared machine the median moves with the load, the best much less).
Needs: pip install gym-electric-motor.
"""
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import gym_electric_motor as gem

ROOT = Path(__file__).resolve().parent.parent
TAU_S = 5e-5


def hil_sim_factor() -> dict:
    """`hil-sim bench speed-step`'s summary (median and best real-time factor and ns per period)."""
    subprocess.run(["cargo", "xtask", "build-tools"], cwd=ROOT, check=True)
    out = subprocess.run(
        [str(ROOT / "target/release/hil-sim"), "bench", "speed-step", "--runs", "20"],
        cwd=ROOT, check=True, capture_output=True, text=True,
    ).stdout
    return json.loads(out)


def gem_factor(seconds: float) -> tuple[float, int]:
    motor = dict(p=1, l_m=1.42, l_sigs=1.44 - 1.42, l_sigr=1.5 - 1.42, j_rotor=0.005, r_s=16.2, r_r=23.2)
    env = gem.make("Cont-CC-SCIM-v0", tau=TAU_S, motor=dict(motor_parameter=motor), supply=dict(u_nominal=310.0))
    env.reset(seed=1)
    n = round(seconds / TAU_S)
    resets = 0
    t0 = time.perf_counter()
    for k in range(n):
        th = 2 * math.pi * 20.0 * k * TAU_S
        a = 0.3 * np.array([math.cos(th), math.cos(th - 2 * math.pi / 3), math.cos(th + 2 * math.pi / 3)])
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            resets += 1
            env.reset()
    return n * TAU_S / (time.perf_counter() - t0), resets


def main() -> int:
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 1.0
    b = hil_sim_factor()
    ours, ns = b["median_real_time_factor"], b["median_ns_per_pwm_period"]
    theirs, resets = gem_factor(seconds)
    print(f"hil-sim speed-step (closed loop, 50 µs control period): {ours:8.1f}× real time "
          f"({ns:.1f} ns per period, median of 20 runs; best run {b['best_real_time_factor']:.1f}×, "
          f"{b['best_ns_per_pwm_period']:.1f} ns)")
    print(f"gym-electric-motor SCIM env, same motor and step, no controller: {theirs:8.3f}× real time "
          f"({seconds} s simulated, {resets} resets)")
    print(f"ratio: hil-sim is {ours / theirs:.0f}× faster (a lower bound: GEM's figure has no controller)")
    return 0 if ours > 0 and theirs > 0 else 1


if __name__ == "__main__":
    sys.exit(main())
