#!/bin/sh
# run-fuzz: libFuzzer on the RTU frame parser for FUZZ_SECONDS (default 60),
# seeded from the committed corpus; new inputs go to a work corpus in the build
# tree (the committed corpus is not touched). Prints executions and coverage.
set -eu
fuzzer="$1"; seeds="$2"; work="$3"
seconds="${FUZZ_SECONDS:-60}"
mkdir -p "$work"
log="$work.log"
echo "fuzzing the Modbus RTU parser for ${seconds} s (seeds: $seeds, work corpus: $work)"
"$fuzzer" -max_total_time="$seconds" -max_len=600 -print_final_stats=1 "$work" "$seeds" >"$log" 2>&1 || {
  tail -n 60 "$log"; echo "run-fuzz: the fuzzer stopped on a finding (log: $log)"; exit 1; }
grep -E '^#[0-9]+[[:space:]]+(INITED|DONE)' "$log" || true
grep -E '^(Done|stat::number_of_executed_units|stat::average_exec_per_sec|stat::new_units_added|stat::peak_rss_mb)' "$log" || true
