#!/usr/bin/env bash
# Cargo runner for the emulated boards: run-qemu.sh MACHINE CPU ELF.
# The program logs through defmt over semihosting; its output is decoded with defmt-print
# when installed (`cargo install defmt-print --locked`), else shown raw. The exit status is
# the program's (semihosting exit), so cargo reports the test result.
set -uo pipefail
machine=$1 cpu=$2 elf=$3
run() {
    qemu-system-arm -cpu "$cpu" -machine "$machine" -nographic \
        -semihosting-config enable=on,target=native -kernel "$elf"
}
if command -v defmt-print >/dev/null; then
    run | defmt-print -e "$elf"
else
    echo "run-qemu.sh: defmt-print not installed; defmt output not decoded" >&2
    run | cat -v
fi
