#!/usr/bin/env python3
"""Cycles per simulated PWM period as llvm-mca predicts them: a layout-independent check of
a change to the simulator's hot loop (`hil-sim bench` measures; this explains).

    python3 tools/mca_period.py [BINARY]     (default: target/release/hil-sim)

Runs `BINARY bench --runs 1` (a warm-up and one run of `speed-step`: 2 × 70 000 periods)
under callgrind with per-instruction counts, keeps the instructions executed about once per
period, splices each hot callee in at its call site (so the list is in execution order),
drops branches and calls, and hands the result to `llvm-mca -mcpu=znver3` as a loop. Prints
the predicted cycles per period for the whole period and, when the drive step is a separate
call, for the drive step and the rest (the plant's period) alone.

Limits: llvm-mca models the core's ports, latencies and window, but not memory dependencies
(a value stored and loaded again costs it nothing), so work moved across the drive's call —
which forces such round trips — must be measured. Needs valgrind and llvm-mca (LLVM ≥ 14);
not run by CI.
"""
import collections
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PERIODS = 2 * 70_000  # `bench --runs 1`: warm-up + one run of speed-step's 70 000 periods
HOT = 0.9  # executions per period for an instruction to count as the loop's


def hot_counts(binary: str) -> collections.Counter:
    out = "/tmp/mca_period.callgrind"
    subprocess.run(["valgrind", "--tool=callgrind", "--dump-instr=yes", "--dump-line=no", "--compress-pos=no",
                    "--compress-strings=no", f"--callgrind-out-file={out}", binary, "bench",
                    "--runs", "1"], check=True, capture_output=True)
    counts, obj, skip = collections.Counter(), "", False
    for line in open(out):
        if line.startswith("ob="):
            obj = line
        if line.startswith("calls="):
            skip = True  # the next line is the call's inclusive cost, not an instruction's
            continue
        m = re.match(r"^(0x[0-9a-f]+) (\d+)", line)
        if m:
            if skip:
                skip = False
            elif "hil-sim" in obj:
                counts[int(m.group(1), 16)] += int(m.group(2))
    return counts


def functions(binary: str, counts) -> dict:
    """Functions executing more than 50 instructions per period: address → (name, hot list)."""
    nm = subprocess.run(["nm", "-n", binary], capture_output=True, text=True, check=True).stdout
    syms = [(int(a, 16), n) for a, _, n in (l.split() for l in nm.splitlines() if len(l.split()) == 3)]
    hot = {}
    for (a, name), (b, _) in zip(syms, syms[1:]):
        if sum(counts.get(x, 0) for x in range(a, b)) / PERIODS <= 50:
            continue
        dis = subprocess.run(["objdump", "-d", "--no-show-raw-insn", f"--start-address={a}",
                              f"--stop-address={b}", binary], capture_output=True, text=True).stdout
        lst = []
        for line in dis.splitlines():
            addr, _, ins = line.partition(":")
            try:
                if counts.get(int(addr.strip(), 16), 0) / PERIODS >= HOT:
                    lst.append(ins.strip())
            except ValueError:
                continue
        hot[a] = (name, lst)
    return hot


def callee(ins: str):
    m = re.match(r"call\s+([0-9a-f]+)", ins)
    return int(m.group(1), 16) if m else None


def body(hot: dict, a: int, depth: int = 0) -> list:
    """`a`'s hot instructions with hot callees spliced in; a callee's part is bracketed by
    `None` markers at depth 0."""
    out = []
    for ins in hot[a][1]:
        c = callee(ins)
        if c in hot and depth < 3:
            out += [None] + [i for i in body(hot, c, depth + 1) if i is not None] + [None]
        elif not re.match(r"(j|ret|call)", ins):
            out.append(re.sub(r"\s*(<.*|#.*)$", "", ins))
    return out


def mca(lines: list) -> float:
    src = "/tmp/mca_period.s"
    Path(src).write_text("\n".join(lines) + "\n")
    r = subprocess.run(["llvm-mca", "-mcpu=znver3", "-iterations=300", src],
                       capture_output=True, text=True, check=True).stdout
    return int(re.search(r"Total Cycles:\s+(\d+)", r).group(1)) / 300


def main() -> int:
    binary = sys.argv[1] if len(sys.argv) > 1 else str(ROOT / "target/release/hil-sim")
    hot = functions(binary, hot_counts(binary))
    called = {callee(i) for _, lst in hot.values() for i in lst}
    root = next(a for a in hot if a not in called and "run" in hot[a][0])
    seq = body(hot, root)
    whole = [i for i in seq if i is not None]
    print(f"hot loop: {len(whole)} instructions, llvm-mca {mca(whole):.1f} cycles per period")
    marks = [n for n, i in enumerate(seq) if i is None]
    if len(marks) >= 2:
        s, e = marks[0], marks[-1]
        drive = [i for i in seq[s:e] if i is not None]
        rest = [i for i in seq[:s] + seq[e:] if i is not None]
        print(f"  drive step alone: {len(drive)} instructions, {mca(drive):.1f} cycles")
        print(f"  the rest alone:   {len(rest)} instructions, {mca(rest):.1f} cycles")
    return 0


if __name__ == "__main__":
    sys.exit(main())
