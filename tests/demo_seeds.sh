#!/usr/bin/env bash
# The demo with other secret poses (--seed 1..N, drawn views, opening angles
# 35-65 deg, roll +-3 deg): every registration must be within 0.3 deg or an
# honest no_match, never a wrong pose; at least 80% must register.
# Usage: demo_seeds.sh HORIZONREG N
set -uo pipefail
bin=$1
n=${2:-20}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
pass=0 nomatch=0 wrong=0
for s in $(seq 1 "$n"); do
  "$bin" demo --output-dir "$out" --seed "$s" > "$out/log.txt"
  if grep -q "PASS" "$out/log.txt"; then pass=$((pass + 1))
  elif grep -q "no match" "$out/log.txt"; then nomatch=$((nomatch + 1))
  else wrong=$((wrong + 1)); echo "wrong pose for seed $s:"; cat "$out/log.txt"; fi
done
echo "demo seeds 1-$n: $pass within 0.3 deg, $nomatch no_match, $wrong wrong"
if [ "$wrong" -gt 0 ] || [ $((pass * 100)) -lt $((n * 80)) ]; then echo "FAIL"; exit 1; fi
