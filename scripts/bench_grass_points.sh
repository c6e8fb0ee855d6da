#!/usr/bin/env bash
# Horizons at many points against GRASS GIS r.horizon, same DEM (N47E009.hgt),
# same points, same step (0.25 deg) and distance (100 km), on this machine:
#  - r.horizon point mode, one coordinate per run (GRASS 8.2), timed as a
#    whole module process inside a running GRASS session (the session's own
#    start-up not counted);
#  - `horizonreg horizon` as a whole process for one point (the launcher and
#    the OpenCV-free horizonreg-horizon);
#  - `horizonreg horizon --points` with 100 points, per point.
# Usage: bench_grass_points.sh HORIZONREG [SHARED_DIR]
set -euo pipefail
bin=$1
shared=${2:-$(dirname "$0")/../../shared}
dem="$shared/dem/N47E009.hgt"
[ -f "$dem" ] || { echo "SKIPPED: $dem is absent"; exit 77; }
command -v grass >/dev/null || { echo "SKIPPED: GRASS GIS (grass-core) is not installed"; exit 77; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python3 - "$work/points.csv" <<'PY'
import math, sys
with open(sys.argv[1], "w") as f:
    f.write("id,lat,lon\n")
    for i in range(100):  # a 10 x 10 grid, 1 km apart, around the Saentis
        f.write(f"p{i},{47.20 + 0.009 * (i // 10):.5f},{9.30 + 0.0133 * (i % 10):.5f}\n")
PY
cat > "$work/grass.sh" <<GRASS
r.in.gdal input=$dem output=dem --quiet
g.region raster=dem
for i in \$(seq 7); do
  s=\$(date +%s%N); r.horizon elevation=dem coordinates=9.35,47.25 step=0.25 maxdistance=100000 > /dev/null 2>&1; e=\$(date +%s%N)
  echo \$(( (e - s) / 1000 ))
done > $work/grass_us.txt
GRASS
grass --tmp-location "$dem" --exec bash "$work/grass.sh" > "$work/grass.log" 2>&1 || { cat "$work/grass.log"; exit 1; }
median() { sort -n | awk '{a[NR]=$1} END {print a[int((NR + 1) / 2)] / 1000}'; }
grass_ms=$(median < "$work/grass_us.txt")
one=()
for _ in $(seq 7); do
  s=$(date +%s%N); "$bin" horizon --dem "$dem" --lat 47.25 --lon 9.35 --step 0.25 -o /dev/null; e=$(date +%s%N)
  one+=($(( (e - s) / 1000 )))
done
one_ms=$(printf '%s\n' "${one[@]}" | median)
many=()
for _ in $(seq 3); do
  s=$(date +%s%N); "$bin" horizon --dem "$dem" --points "$work/points.csv" --step 0.25 --format csv -o "$work/out.csv"; e=$(date +%s%N)
  many+=($(( (e - s) / 1000 )))
done
many_ms=$(printf '%s\n' "${many[@]}" | median)
rows=$(($(wc -l < "$work/out.csv") - 1))
[ "$rows" -eq $((100 * 1440)) ] || { echo "FAIL: --points wrote $rows rows, expected 144000"; exit 1; }
printf 'r.horizon point mode, one point per process        %8.1f ms per point\n' "$grass_ms"
printf 'horizonreg horizon, one point per process          %8.1f ms per point  (%.2fx r.horizon)\n' "$one_ms" \
  "$(echo "$one_ms / $grass_ms" | bc -l)"
printf 'horizonreg horizon --points, 100 points, one process %6.1f ms per point  (%.1fx faster than r.horizon)\n' \
  "$(echo "$many_ms / 100" | bc -l)" "$(echo "$grass_ms * 100 / $many_ms" | bc -l)"
