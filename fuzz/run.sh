#!/usr/bin/env bash
# fuzz/run.sh SECONDS [TARGET ...]: every fuzz target (or those named) for
# SECONDS each, on all cores (libFuzzer's -fork; JOBS=N for N), from its corpus
# (fuzz/corpus/TARGET, kept between runs, not committed) and its seeds
# (fuzz/seeds/TARGET). Builds the targets with libFuzzer's coverage
# instrumentation on the stable toolchain, as `cargo fuzz build -O -s
# none -a` does (debug assertions and overflow checks on; codegen units
# left at cargo's default, so the build uses every core), so cargo-fuzz
# need not be installed. A crash, a mismatch
# (the encoder target) or a non-finite field (the motion target) stops the
# run with libFuzzer's report and a non-zero exit; the input is saved in
# fuzz/artifacts/TARGET/. Each target's last lines (executions, coverage)
# are printed at the end.
set -euo pipefail
cd "$(dirname "$0")"
seconds=${1:?usage: fuzz/run.sh SECONDS [TARGET ...]}
shift
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(decoder y4m flo encoder motion)
triple=$(rustc -vV | sed -n 's/^host: //p')
export RUSTFLAGS="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares --cfg fuzzing -Cllvm-args=-simplifycfg-branch-fold-threshold=0 \
-Cllvm-args=-sanitizer-coverage-stack-depth -Cdebug-assertions"
cargo build --release --target "$triple" --bins --config 'profile.release.debug="line-tables-only"'
jobs=${JOBS:-$(nproc)}
declare -A max_len=([decoder]=8192 [y4m]=4096 [flo]=4096 [encoder]=512 [motion]=256)
for t in "${targets[@]}"; do
  mkdir -p "corpus/$t" "artifacts/$t" logs
  echo "== $t: ${seconds} s on $jobs cores"
  "target/$triple/release/$t" "corpus/$t" "seeds/$t" -fork="$jobs" -max_total_time="$seconds" \
    -max_len="${max_len[$t]}" -artifact_prefix="artifacts/$t/" -print_final_stats=1 > "logs/$t.log" 2>&1 \
    || { tail -40 "logs/$t.log"; echo "fuzz target $t failed (input in fuzz/artifacts/$t/)" >&2; exit 1; }
  grep -E '^#[0-9]+' "logs/$t.log" | tail -1
done
