#!/usr/bin/env bash
# CLI contract of `horizonreg horizon` (DESIGN.md): outputs and formats on a
# real DEM, and bad input -> one clear line on stderr, exit code 2, no
# output file. Usage: cli_test.sh HORIZONREG SHARED_DIR
set -uo pipefail
bin=$1
shared=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
pass=0 fail=0
ok() { pass=$((pass + 1)); echo "ok   $1"; }
bad() { fail=$((fail + 1)); echo "FAIL $1"; }

# expect_exit2 NAME ARGS...: exit 2, exactly one stderr line, no output file.
expect_exit2() {
  local name=$1; shift
  rm -f "$work/out.json" "$work/out.png"
  "$bin" "$@" > "$work/stdout" 2> "$work/stderr"
  local rc=$?
  local lines; lines=$(wc -l < "$work/stderr")
  if [ "$rc" -eq 2 ] && [ "$lines" -eq 1 ] && [ ! -s "$work/stdout" ] && [ ! -e "$work/out.json" ] && [ ! -e "$work/out.png" ]; then
    ok "$name: $(cat "$work/stderr")"
  else
    bad "$name: exit $rc, $lines stderr lines: $(head -c 300 "$work/stderr")"
  fi
}

npz=/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz
if [ -f "$npz" ]; then dem=$npz lat=36.6 lon=-84.25; else dem=""; fi
if [ -d "$shared/dem" ]; then hgt="$shared/dem/N47E009.hgt"; else hgt=""; fi

# --- success paths ---
if [ -n "$dem" ]; then
  if "$bin" horizon --dem "$dem" --lat $lat --lon $lon -o "$work/h.json" --plot "$work/h.png" --ridges; then
    python3 - "$work/h.json" <<'PY' && ok "json: 1440 bins, DESIGN.md fields, ridges" || bad "json contents"
import json, sys
j = json.load(open(sys.argv[1]))
for k in ["observer", "step_deg", "refraction", "azimuth_deg", "elevation_deg", "distance_m", "lat", "lon", "height_m", "ridges"]:
    assert k in j, k
assert len(j["elevation_deg"]) == 1440 and j["azimuth_deg"][4] == 1.0
assert all(e is not None for e in j["elevation_deg"])
assert set(j["observer"]) >= {"lat", "lon", "eye_height_m"}
PY
    file "$work/h.png" | grep -q "PNG image data, 1800 x 560" && ok "plot png" || bad "plot png"
  else
    bad "horizon json run"
  fi
  "$bin" horizon --dem "$dem" --lat $lat --lon $lon --format csv --step 1 > "$work/h.csv" \
    && [ "$(wc -l < "$work/h.csv")" -eq 361 ] && head -1 "$work/h.csv" | grep -q "^azimuth_deg,elevation_deg,distance_m,lat,lon,height_m$" \
    && ok "csv to stdout, --step 1" || bad "csv"
  "$bin" horizon --dem "$dem" --lat $lat --lon $lon --format geojson -o "$work/h.geojson" && python3 - "$work/h.geojson" <<'PY' && ok "geojson LineString 3D" || bad "geojson"
import json, sys
j = json.load(open(sys.argv[1]))
line = j["features"][0]["geometry"]
assert j["type"] == "FeatureCollection" and line["type"] == "LineString"
assert len(line["coordinates"]) == 1441 and len(line["coordinates"][0]) == 3
assert j["features"][1]["geometry"]["type"] == "Point"
PY
  a=$("$bin" horizon --dem "$dem" --lat $lat --lon $lon --refraction 0 --format csv | sed -n 2p | cut -d, -f2)
  b=$("$bin" horizon --dem "$dem" --lat $lat --lon $lon --format csv | sed -n 2p | cut -d, -f2)
  [ "$a" != "$b" ] && ok "refraction changes the angles ($a vs $b)" || bad "refraction has no effect"
  a=$("$bin" horizon --dem "$dem" --lat $lat --lon $lon --alt 2000 --format csv | sed -n 2p | cut -d, -f2)
  python3 -c "import sys; sys.exit(0 if float('$a') < 0 else 1)" && ok "--alt 2000 sees negative angles ($a)" || bad "--alt"
else
  echo "SKIPPED: success paths need python-matplotlib-data ($npz)"
fi

# --- bad input ---
d=${dem:-$hgt}
if [ -n "$d" ]; then
  expect_exit2 "missing dem" horizon --dem "$work/nope.hgt" --lat 1 --lon 1 -o "$work/out.json"
  echo "not a raster" > "$work/text.tif"
  expect_exit2 "non-raster dem" horizon --dem "$work/text.tif" --lat 1 --lon 1 -o "$work/out.json"
  expect_exit2 "directory as dem" horizon --dem "$work" --lat 1 --lon 1 -o "$work/out.json"
  expect_exit2 "observer outside" horizon --dem "$d" --lat 10 --lon 10 -o "$work/out.json" --plot "$work/out.png"
  expect_exit2 "nan latitude" horizon --dem "$d" --lat nan --lon 10 -o "$work/out.json"
  expect_exit2 "latitude 91" horizon --dem "$d" --lat 91 --lon 10 -o "$work/out.json"
  expect_exit2 "longitude 400" horizon --dem "$d" --lat 10 --lon 400 -o "$work/out.json"
  expect_exit2 "step 0.7" horizon --dem "$d" --lat 10 --lon 10 --step 0.7 -o "$work/out.json"
  expect_exit2 "step 0" horizon --dem "$d" --lat 10 --lon 10 --step 0 -o "$work/out.json"
  expect_exit2 "step nan" horizon --dem "$d" --lat 10 --lon 10 --step nan -o "$work/out.json"
  expect_exit2 "step text" horizon --dem "$d" --lat 10 --lon 10 --step abc -o "$work/out.json"
  expect_exit2 "negative max distance" horizon --dem "$d" --lat 10 --lon 10 --max-distance -5 -o "$work/out.json"
  expect_exit2 "agl and alt" horizon --dem "$d" --lat 10 --lon 10 --agl 2 --alt 100 -o "$work/out.json"
  expect_exit2 "unknown format" horizon --dem "$d" --lat 10 --lon 10 --format xml -o "$work/out.json"
  expect_exit2 "missing --lat" horizon --dem "$d" --lon 10 -o "$work/out.json"
  expect_exit2 "unknown command" frobnicate
  expect_exit2 "unwritable output" horizon --dem "${dem:-$hgt}" --lat ${lat:-47.5} --lon ${lon:-9.5} -o "/nonexistent/dir/out.json"
  if command -v gdal_create >/dev/null; then
    gdal_create -q -of GTiff -outsize 20 20 -bands 1 -ot Int16 -burn -32768 -a_nodata -32768 -a_srs EPSG:4326 \
      -a_ullr 9 48 9.02 47.98 "$work/allvoid.tif"
    expect_exit2 "all-void dem" horizon --dem "$work/allvoid.tif" --lat 47.99 --lon 9.01 -o "$work/out.json"
  fi
fi
if [ -n "$hgt" ]; then
  head -c 100000 "$hgt" > "$work/N47E009.hgt"
  expect_exit2 "truncated hgt" horizon --dem "$work/N47E009.hgt" --lat 47.5 --lon 9.5 -o "$work/out.json"
else
  echo "SKIPPED: truncated-HGT case needs ../shared"
fi
# --- skyline ---
scene="$shared/scenes/dev/rainier_01.jpg"
if [ -f "$scene" ]; then
  "$bin" skyline "$scene" --json "$work/s.json" --debug "$work/s.png" && python3 - "$work/s.json" <<'PY' && ok "skyline json on a dev scene" || bad "skyline json"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["width"] == 1024 and j["height"] == 683 and len(j["y"]) == 1024 and len(j["confidence"]) == 1024
assert sum(v is not None for v in j["y"]) > 900
PY
  file "$work/s.png" | grep -q "PNG image data, 1024 x 683" && ok "skyline debug png" || bad "skyline debug png"
  head -c 20000 "$scene" > "$work/cut.jpg"
  expect_exit2 "truncated jpeg" skyline "$work/cut.jpg" --json "$work/out.json"
else
  echo "SKIPPED: skyline dev-scene cases need ../shared"
fi
: > "$work/empty.jpg"
expect_exit2 "empty image file" skyline "$work/empty.jpg" --json "$work/out.json"
expect_exit2 "missing image" skyline "$work/nope.jpg" --json "$work/out.json"
expect_exit2 "text as image" skyline "$work/text.tif" --json "$work/out.json"
expect_exit2 "roll hint 90" skyline "$work/empty.jpg" --roll 90 --json "$work/out.json"
if command -v gdal_create >/dev/null; then
  gdal_create -q -of GTiff -outsize 64 48 -bands 3 -ot Byte -burn 128 "$work/grey.tif"
  gdal_translate -q -of PNG "$work/grey.tif" "$work/grey.png"
  "$bin" skyline "$work/grey.png" > "$work/grey.json" && python3 -c "
import json, sys; j = json.load(open('$work/grey.json')); sys.exit(0 if all(v is None for v in j['y']) and len(j['y']) == 64 else 1)" \
    && ok "uniform image gives all-null, exit 0" || bad "uniform image"
  gdal_create -q -of GTiff -outsize 6 5 -bands 3 -ot Byte -burn 128 "$work/tiny.tif"
  gdal_translate -q -of PNG "$work/tiny.tif" "$work/tiny.png"
  expect_exit2 "register on a 6 x 5 image" register "$work/tiny.png" --dem "$work/tiny.tif" --lat 0 --lon 0 --agl 2 \
    --json "$work/out.json"
  grep -q "tiny.png" "$work/stderr" && ok "the 6 x 5 image's error names the file" || bad "tiny image error: $(cat "$work/stderr")"
fi
# --- register ---
if [ -d "$shared/scenes/dev" ]; then
  sc="$shared/scenes/dev"
  "$bin" register "$sc/zion_01.jpg" --dem "$shared/dem/zion_srtm.tif" --lat 37.368515 --lon -113.161021 --agl 1.7 \
    --json "$work/r.json" --overlay "$work/r.png" && python3 - "$work/r.json" "$sc/zion_01.truth.json" <<'PY' \
    && ok "register json on a dev scene (DESIGN.md fields, pose within 0.3 deg)" || bad "register json"
import json, sys
j, t = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
for k in ["status", "observer", "width", "height", "azimuth_deg", "pitch_deg", "roll_deg", "hfov_deg", "focal_px",
          "cx_px_per_deg", "cy_px_per_deg", "rms_px", "azimuth_sigma_deg", "pitch_sigma_deg", "hypotheses", "timing_ms"]:
    assert k in j, k
for k in ["horizon", "skyline", "match", "total"]:
    assert k in j["timing_ms"], k
assert j["status"] == "registered", j
assert abs((j["azimuth_deg"] - t["yaw_deg"] + 180) % 360 - 180) < 0.3 and abs(j["pitch_deg"] - t["pitch_deg"]) < 0.2
PY
  file "$work/r.png" | grep -q "PNG image data, 1024 x 683" && ok "register overlay png" || bad "register overlay png"
  "$bin" register "$sc/zion_01.jpg" --dem "$shared/dem/zion_srtm.tif" --lat 37.368515 --lon -113.161021 --agl 1.7 \
    --json "$work/rk.json" --skyline-out "$work/rk_sky.json" && python3 - "$work/rk_sky.json" "$sc/zion_01.truth.json" <<'PY' \
    && ok "register --skyline-out: a skyline JSON near the truth" || bad "register --skyline-out"
import json, sys
s, t = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
assert s["width"] == 1024 and s["height"] == 683 and len(s["y"]) == 1024 and len(s["confidence"]) == 1024, s.keys()
near = sum(1 for y, r in zip(s["y"], t["skyline_row"]) if y is not None and r is not None and 0 < r < 683 and abs(y - r) <= 2)
assert near >= 0.9 * 1024, near
PY
  # `skyline --json` then `register --skyline` registers as `register` does
  # alone: the JSON carries the edges the matching reads below raised
  # boundaries ("y_alt"; without them zion_01 came 0.013 deg and 0.13 deg of
  # opening angle away).
  "$bin" skyline "$sc/zion_01.jpg" --json "$work/z_sky.json" \
    && "$bin" register "$sc/zion_01.jpg" --dem "$shared/dem/zion_srtm.tif" --lat 37.368515 --lon -113.161021 --agl 1.7 \
      --skyline "$work/z_sky.json" --json "$work/r2.json" \
    && python3 - "$work/r.json" "$work/r2.json" "$work/z_sky.json" <<'PY' \
    && ok "skyline --json then register --skyline: the pose register finds alone" || bad "skyline -> register --skyline"
import json, sys
a, b, s = (json.load(open(p)) for p in sys.argv[1:4])
assert sum(v is not None for v in s["y_alt"]) > 50, "no y_alt"
assert b["status"] == "registered", b
for k, tol in [("azimuth_deg", 0.002), ("pitch_deg", 0.002), ("roll_deg", 0.002), ("hfov_deg", 0.01)]:
    assert abs(a[k] - b[k]) <= tol, (k, a[k], b[k])
PY
  python3 -c "
import json, sys
s = json.load(open(sys.argv[1])); s['y_alt'] = s['y_alt'][:-1]; json.dump(s, open(sys.argv[2], 'w'))" \
    "$work/z_sky.json" "$work/z_bad.json"
  expect_exit2 "register --skyline with a short y_alt" register "$sc/zion_01.jpg" --dem "$shared/dem/zion_srtm.tif" \
    --lat 37.368515 --lon -113.161021 --skyline "$work/z_bad.json" --json "$work/out.json"
  expect_exit2 "register unwritable --skyline-out" register "$sc/zion_01.jpg" --dem "$shared/dem/zion_srtm.tif" \
    --lat 37.368515 --lon -113.161021 --json "$work/out.json" --skyline-out "/nonexistent/dir/s.json"
  "$bin" register "$sc/zion_01.jpg" --dem "$shared/dem/zion_srtm.tif" --lat 37.368515 --lon -113.161021 \
    --initial 313.5,-1.5,1.5,40.5 | grep -q '"status": "registered"' && ok "register --initial refines a known pose" || bad "register --initial"
  expect_exit2 "register bad --initial" register "$sc/zion_01.jpg" --dem "$shared/dem/zion_srtm.tif" --lat 37.37 --lon -113.16 --initial 1,2,3 --json "$work/out.json"
  "$bin" register "$sc/alpsfog_00.jpg" --dem "$shared/dem/N47E009.hgt" --lat 47.3 --lon 9.8 > "$work/fog.json" \
    && grep -q '"status": "no_match"' "$work/fog.json" && ok "fog scene: no_match, exit 0" || bad "fog scene"
  "$bin" register "$sc/zion_01.jpg" --dem "$shared/dem/zion_srtm.tif" --sensors "$sc/zion_01.sensors.json" \
    > "$work/rs.json" && grep -q '"status": "registered"' "$work/rs.json" \
    && ok "register takes the position from --sensors" || bad "register position from --sensors"
  expect_exit2 "register without a position" register "$sc/zion_01.jpg" --dem "$shared/dem/zion_srtm.tif" --json "$work/out.json"
  expect_exit2 "register bad --hfov-range" register "$sc/zion_01.jpg" --dem "$shared/dem/zion_srtm.tif" --lat 37.26 --lon -112.97 --hfov-range 60 --json "$work/out.json"
  expect_exit2 "register outside the DEM" register "$sc/zion_01.jpg" --dem "$shared/dem/zion_srtm.tif" --lat 10 --lon 10 --json "$work/out.json"
  echo '{"inclinometer_pitch_deg": "up"}' > "$work/bad_sensors.json"
  expect_exit2 "register bad sensors file" register "$sc/zion_01.jpg" --dem "$shared/dem/zion_srtm.tif" --lat 37.26 --lon -112.97 --sensors "$work/bad_sensors.json" --overlay "$work/out.png"
  expect_exit2 "register missing image" register "$work/nope.jpg" --dem "$shared/dem/zion_srtm.tif" --lat 37.26 --lon -112.97 --json "$work/out.json"
  # A directory or a device given for a file (a stream opens a directory on
  # Linux: its size read as 8 EB, its first read an internal error; /dev/zero
  # has no size and was read until the OOM killer came).
  mkdir -p "$work/adir"
  expect_exit2 "register directory as image" register "$work/adir" --dem "$shared/dem/zion_srtm.tif" --lat 37.26 --lon -112.97 --json "$work/out.json"
  expect_exit2 "register /dev/zero as image" register /dev/zero --dem "$shared/dem/zion_srtm.tif" --lat 37.26 --lon -112.97 --json "$work/out.json"
  for opt in --camera --sensors --skyline; do
    expect_exit2 "register directory as $opt" register "$sc/zion_01.jpg" --dem "$shared/dem/zion_srtm.tif" --lat 37.26 --lon -112.97 $opt "$work/adir" --json "$work/out.json"
    expect_exit2 "register /dev/zero as $opt" register "$sc/zion_01.jpg" --dem "$shared/dem/zion_srtm.tif" --lat 37.26 --lon -112.97 $opt /dev/zero --json "$work/out.json"
  done
  expect_exit2 "register directory as --json" register "$sc/zion_01.jpg" --dem "$shared/dem/zion_srtm.tif" --lat 37.26 --lon -112.97 --json "$work/adir/"
  [ -z "$(ls -A "$work/adir")" ] && ok "no temporary file left in the directory given as --json" || bad "files left in $work/adir: $(ls -A "$work/adir")"
  if [ -f "$work/grey.png" ]; then
    "$bin" register "$work/grey.png" --dem "$shared/dem/zion_srtm.tif" --lat 37.26 --lon -112.97 > "$work/g.json" \
      && grep -q '"status": "no_match"' "$work/g.json" && ok "uniform image: no_match, exit 0" || bad "uniform image register"
  fi
  # overlay and render
  "$bin" overlay "$sc/zion_01.jpg" --pose "$work/r.json" --dem "$shared/dem/zion_srtm.tif" \
    --landmarks "$shared/landmarks/zion.geojson" -o "$work/ov.png" \
    && file "$work/ov.png" | grep -q "PNG image data, 1024 x 683" && ok "overlay from a register pose" || bad "overlay"
  expect_exit2 "overlay directory as --pose" overlay "$sc/zion_01.jpg" --pose "$work/adir" --dem "$shared/dem/zion_srtm.tif" -o "$work/out.png"
  expect_exit2 "overlay /dev/zero as --landmarks" overlay "$sc/zion_01.jpg" --pose "$work/r.json" --dem "$shared/dem/zion_srtm.tif" --landmarks /dev/zero -o "$work/out.png"
  expect_exit2 "overlay with a no_match pose" overlay "$sc/zion_01.jpg" --pose "$work/fog.json" --dem "$shared/dem/zion_srtm.tif" -o "$work/out.png"
  echo 'name,lat,lon' > "$work/bad.csv"; echo 'X,95,10' >> "$work/bad.csv"
  expect_exit2 "overlay bad landmarks" overlay "$sc/zion_01.jpg" --pose "$work/r.json" --dem "$shared/dem/zion_srtm.tif" --landmarks "$work/bad.csv" -o "$work/out.png"
  "$bin" render --dem "$shared/dem/zion_srtm.tif" --lat 37.368515 --lon -113.161021 --azimuth 312 --hfov 40 \
    --size 640x400 -o "$work/rv.png" --panorama "$work/pano.png" \
    && file "$work/rv.png" | grep -q "PNG image data, 640 x 400" && file "$work/pano.png" | grep -q "PNG image data, 3600 x" \
    && ok "render view and panorama" || bad "render"
  expect_exit2 "render bad --size" render --dem "$shared/dem/zion_srtm.tif" --lat 37.37 --lon -113.16 --azimuth 0 --size 640 -o "$work/out.png"
  expect_exit2 "render pitch 100" render --dem "$shared/dem/zion_srtm.tif" --lat 37.37 --lon -113.16 --azimuth 0 --pitch 100 -o "$work/out.png"
  # track
  q="$shared/scenes/seq"
  if [ -d "$q" ]; then
    printf 'frame,compass_yaw_deg,inclinometer_pitch_deg,inclinometer_roll_deg\n0,36.8,-3.2,-1.1\n1,junk,-3.0,0.1\n2,nan,-3.0,0.0\n' > "$work/s.csv"
    "$bin" track "$q/rainier_pan_%04d.jpg" --dem "$shared/dem/mt_rainier_90m.tif" --lat 46.86146 --lon -121.57288 \
      --sensors "$work/s.csv" --fps 10 --max-frames 3 --poses "$work/p.csv" -o "$work/t.mp4" 2> "$work/track.err" \
      && [ "$(grep -c 'skipped' "$work/track.err")" -eq 2 ] && [ "$(wc -l < "$work/p.csv")" -eq 4 ] \
      && head -1 "$work/p.csv" | grep -q "^frame,azimuth_deg,pitch_deg,roll_deg,hfov_deg,source$" && [ -s "$work/t.mp4" ] \
      && ok "track: poses CSV, video, garbage sensor rows skipped with warnings" || bad "track $(cat "$work/track.err")"
    expect_exit2 "track unopenable video" track "$work/nope.mp4" --dem "$shared/dem/mt_rainier_90m.tif" --lat 46.86 --lon -121.57 --poses "$work/out.json"
    # No raw OpenCV, GStreamer or FFmpeg lines on stderr: one line of ours.
    echo "not a video" > "$work/text.mp4"
    expect_exit2 "track text file as video" track "$work/text.mp4" --dem "$shared/dem/mt_rainier_90m.tif" --lat 46.86 --lon -121.57 --poses "$work/out.json"
    expect_exit2 "track directory as video" track "$work/adir" --dem "$shared/dem/mt_rainier_90m.tif" --lat 46.86 --lon -121.57 --poses "$work/out.json"
    printf 'a,b\n1,2\n' > "$work/nohead.csv"
    expect_exit2 "track sensor log without frame column" track "$q/rainier_pan_%04d.jpg" --dem "$shared/dem/mt_rainier_90m.tif" --lat 46.86 --lon -121.57 --sensors "$work/nohead.csv" --poses "$work/out.json"
  fi
else
  echo "SKIPPED: register dev-scene cases need ../shared"
fi
"$bin" --help > /dev/null && ok "--help exits 0" || bad "--help"
"$bin" horizon --help | grep -q -- "--max-distance" && ok "horizon --help lists options" || bad "horizon --help"

echo "cli_test: $pass passed, $fail failed"
[ "$fail" -eq 0 ]
