#!/usr/bin/env bash
# The sensitive command for all three posts (Keras), timed on this machine: unchanged, and under a real
# change of arithmetic (XLA fast math) that sends every twin through.
set -u
cd "$(dirname "$0")/../../.."
out=${OUT:-timing}; mkdir -p "$out"
rm -rf /tmp/time-unchanged /tmp/time-fastmath
{ /usr/bin/time -v .venv/bin/keras-rl check --tier sensitive --workers 2 --no-progress --out /tmp/time-unchanged ; } > "$out"/unchanged.txt 2>&1
echo "exit $?" >> "$out"/unchanged.txt
if [ "${1:-}" = "both" ]; then
{ XLA_FLAGS=--xla_cpu_enable_fast_math=true /usr/bin/time -v .venv/bin/keras-rl check --tier sensitive --workers 2 --no-progress --out /tmp/time-fastmath ; } > "$out"/fastmath.txt 2>&1
echo "exit $?" >> "$out"/fastmath.txt
fi
