#!/usr/bin/env bash
# Runs libFuzzer targets (`make fuzz`, built with HORIZONREG_FUZZ=ON) for a
# given time each, one after the other under `nice`, and prints per target
# the seconds, executions, executions per second, final coverage (cov: edges,
# ft: features) and what was found. New inputs go to BUILD/fuzz-corpus/<t>
# (the checked-in seeds in fuzz/corpus/<t> are only read); crashes, leaks and
# timeouts to BUILD/fuzz-artifacts/<t>/, logs to BUILD/fuzz-logs/<t>.log.
# Usage: run_fuzz.sh BUILD SECONDS TARGET...      (exit 1 if anything was found)
# Replay only (fuzz/corpus + fuzz/regressions, each input once):
#        run_fuzz.sh --replay BUILD TARGET...
set -uo pipefail
src=$(cd "$(dirname "$0")/.." && pwd)

max_len() {  # bytes a target's inputs may grow to
  case $1 in
    image | dem) echo 65536 ;;
    exif) echo 16384 ;;
    *) echo 4096 ;;
  esac
}

if [ "${1:-}" = --replay ]; then
  build=$2; shift 2
  status=0
  for t in "$@"; do
    dirs=("$src/fuzz/corpus/$t")
    [ -d "$src/fuzz/regressions/$t" ] && dirs+=("$src/fuzz/regressions/$t")
    if "$build/fuzz/fuzz_$t" -runs=0 -rss_limit_mb=2048 -timeout=10 "${dirs[@]}" > "$build/fuzz_replay_$t.log" 2>&1; then
      echo "fuzz replay $t: ok ($(grep -ho 'INITED.*' "$build/fuzz_replay_$t.log" | head -1))"
    else
      echo "fuzz replay $t: FAILED, see $build/fuzz_replay_$t.log"; status=1
    fi
  done
  exit $status
fi

build=$1 seconds=$2; shift 2
mkdir -p "$build/fuzz-logs"
rows=()
status=0
for t in "$@"; do
  corpus=$build/fuzz-corpus/$t artifacts=$build/fuzz-artifacts/$t log=$build/fuzz-logs/$t.log
  mkdir -p "$corpus" "$artifacts"
  echo "fuzz $t: ${seconds} s ..."
  start=$(date +%s)
  touch "$log.start"
  nice -n 10 "$build/fuzz/fuzz_$t" -max_total_time="$seconds" -max_len="$(max_len "$t")" -rss_limit_mb=2048 \
    -timeout=10 -print_final_stats=1 -artifact_prefix="$artifacts/" "$corpus" "$src/fuzz/corpus/$t" > "$log" 2>&1
  rc=$?
  elapsed=$(($(date +%s) - start))
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  last=$(grep -E '^#[0-9]+.*cov: ' "$log" | tail -1)
  cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<< "$last")
  ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<< "$last")
  found=$(find "$artifacts" -type f -newer "$log.start" | wc -l)  # this run's only
  what=none
  if [ "$rc" -ne 0 ] || [ "$found" -gt 0 ]; then
    what="exit $rc, $found new artifact(s) in $artifacts: $(grep -m1 -E '^==[0-9]+==ERROR|^SUMMARY|runtime error|ERROR: libFuzzer' "$log" | cut -c1-100)"
    status=1
  fi
  rows+=("$(printf '%-12s %6s %10s %8s %6s %6s  %s' "$t" "$elapsed" "${execs:-?}" "${rate:-?}" "${cov:-?}" "${ft:-?}" "$what")")
done
printf '%-12s %6s %10s %8s %6s %6s  %s\n' target seconds execs execs/s cov ft findings
printf '%s\n' "${rows[@]}"
exit $status
