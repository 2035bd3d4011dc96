#!/usr/bin/env bash
# The bit-identity set of a behaviour-neutral change (issue 48's acceptance): sha256 of the
# fault matrices of the shipped drive (seed 0), the 24 V drive (seed 3) and the 3 300 V
# template as `design tune --speed p` makes it (seed 0; `auto` refuses it on the default
# requirements, issue 51), of the traces of three scenarios and of the
# tuned drive file. Run it before and after a change and compare the two files it prints
# (summary.json is left out: it holds wall-clock figures).
#   usage: tools/identity_sums.sh OUT_DIR      (builds hil-sim and design in release first)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: tools/identity_sums.sh OUT_DIR}
rm -rf "$out" && mkdir -p "$out"
cargo build --quiet --release -p hil-sim -p design
h=./target/release/hil-sim
./target/release/design tune --template drives/krause-3300v.toml --motor krause-2300v-500hp --speed p \
    --out "$out/krause-tuned.toml" > "$out/tune.log" 2>&1
# The matrices exit 1 on a failing row: the sums still say what changed.
$h faults drive.toml --seed 0 --out "$out/f0" > "$out/f0.log" 2>&1 || true
$h faults drives/em-synergy-24v.toml --seed 3 --out "$out/f24" > "$out/f24.log" 2>&1 || true
$h faults "$out/krause-tuned.toml" --seed 0 --out "$out/fk" > "$out/fk.log" 2>&1 || true
for s in speed-step speed-step-sensors seed000-fig11; do
    $h run "$s" --out "$out/$s" > "$out/$s.log" 2>&1 || true
done
(cd "$out" && sha256sum krause-tuned.toml f0/faults.json f24/faults.json fk/faults.json ./*/trace.csv) \
    | tee "$out/sums"
