#!/usr/bin/env bash
# Runs fuzz targets for a while each: `fuzz/run.sh SECONDS [TARGET…]`
# (default: every target). Needs the nightly toolchain and cargo-fuzz.
# A crash, a hang (an input taking over 10 s) or a runaway allocation
# (over 2 GiB) stops the run and leaves the input in fuzz/artifacts/.
# No sanitizer (`-s none`): the crate forbids unsafe code, so what the
# fuzzers look for is a panic, a hang or a runaway allocation, which
# libFuzzer catches alone. AddressSanitizer would check only the C
# libraries the readers link, at twice the build time and fewer inputs
# a second (docs/decisions.md, "CI on a fresh machine").
set -euo pipefail
cd "$(dirname "$0")"
seconds=${1:-20}
shift || true
targets=("$@")
./seed.sh
if [ ${#targets[@]} -eq 0 ]; then
    targets=(stl obj dae gltf urdf scene session_json session_csv recording live ros_recording rosmsg settings mesh_surface calibration stretches pair press synth foxglove_readback)
    # Every target built in one cargo call first, so that their links
    # share the cores: a build per `fuzz run` linked them one at a time
    # (after a change to the crate, about 30 s a target in CI; all 12 in
    # one call: 78 s on the 2-core VM).
    cargo +nightly fuzz build -O -s none
fi
for t in "${targets[@]}"; do
    echo "== fuzz $t for $seconds s"
    cargo +nightly fuzz run "$t" -O -s none -- -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
        -max_len=262144 -print_final_stats=1 2>&1 | grep -E "^(Done|stat::number_of_executed_units|==|SUMMARY|.*(panicked|ERROR|timeout))" || true
    if [ -n "$(ls artifacts/"$t" 2>/dev/null)" ]; then
        echo "fuzz target $t found a failing input: fuzz/artifacts/$t/" >&2
        exit 1
    fi
done
