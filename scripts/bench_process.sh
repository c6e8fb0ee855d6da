#!/usr/bin/env bash
# Whole-process timing of `horizonreg horizon` (median of 15 runs), next to
# the paper's figures. Usage: bench_process.sh HORIZONREG [SHARED_DIR]
set -euo pipefail
bin=$1
shared=${2:-$(dirname "$0")/../../shared}
run() {  # run NAME ARGS...: prints the median wall time in ms
  local name=$1; shift
  local times=()
  for _ in $(seq 15); do
    local t0 t1; t0=$(date +%s%N); "$bin" "$@" > /dev/null; t1=$(date +%s%N)
    times+=($(( (t1 - t0) / 1000 )))
  done
  local med; med=$(printf '%s\n' "${times[@]}" | sort -n | sed -n 8p)
  printf '  %-58s %8.1f ms\n' "$name" "$(echo "$med / 1000" | bc -l)"
}
echo "horizonreg horizon as a whole process (median of 15; paper: 40 s full tile, 4 s +-15 km, 200 MHz Pentium Pro)"
if [ -d "$shared/dem" ]; then
  run "3\" tile 1201x1201 (mt_rainier_90m.tif), 0.25 deg, 100 km" horizon --dem "$shared/dem/mt_rainier_90m.tif" --lat 46.5 --lon -121.5
  run "3\" tile, +-15 km window" horizon --dem "$shared/dem/mt_rainier_90m.tif" --lat 46.5 --lon -121.5 --max-distance 15000
  run "3\" HGT tile N47E009.hgt, 0.25 deg, 100 km" horizon --dem "$shared/dem/N47E009.hgt" --lat 47.5 --lon 9.5
  run "1\" tile 3601x3601 (N48W125.hgt), 0.25 deg, 100 km" horizon --dem "$shared/dem/N48W125.hgt" --lat 48.5 --lon -124.5
  echo "horizonreg register as a whole process, 1024 x 683 dev scene (median of 15; issue target <= 100 ms; paper: 0.5 s matching)"
  truth="$shared/scenes/dev/rainier_01.truth.json"
  read -r lat lon agl < <(python3 -c "import json,sys; t=json.load(open(sys.argv[1])); print(t['lat'], t['lon'], t['agl_m'])" "$truth")
  run "rainier_01.jpg, mt_rainier_90m.tif (3\" tile, 100 km)" register "$shared/scenes/dev/rainier_01.jpg" \
    --dem "$shared/dem/mt_rainier_90m.tif" --lat "$lat" --lon "$lon" --agl "$agl"
  echo "start-up alone (loading GDAL's and OpenCV's shared libraries):"
  run "horizonreg --version" --version
else
  echo "SKIPPED: ../shared is absent"
fi
