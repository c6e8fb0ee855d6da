#!/bin/bash
# Resource limits and library warnings (issue 10): inputs that would take
# unbounded memory get one clear line and exit 2 within bounded memory, and
# what a codec library prints reaches the user only in our words. Needs only
# generated files and Debian's jacksboro DEM.
set -u
BIN=$1
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
JACKSBORO=/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz
[ -f "$JACKSBORO" ] || { echo "SKIPPED: python-matplotlib-data is not installed"; exit 77; }
python3 - "$TMP" <<'PYEOF'
import os, struct, sys
t = sys.argv[1]
sof = b'\xff\xc0' + struct.pack('>HBHHB', 11, 8, 20000, 30000, 1) + b'\x01\x11\x00'
open(f'{t}/huge.jpg', 'wb').write(b'\xff\xd8' + sof + b'\x00' * 100 + b'\xff\xd9')   # declares 30000 x 20000
png = b'\x89PNG\r\n\x1a\n' + struct.pack('>I', 13) + b'IHDR' + struct.pack('>IIBBBBB', 40000, 40000, 8, 2, 0, 0, 0)
open(f'{t}/huge.png', 'wb').write(png + b'\x00' * 16)
open(f'{t}/huge.vrt', 'w').write('''<VRTDataset rasterXSize="100000" rasterYSize="50000"><SRS>EPSG:4326</SRS>
<GeoTransform>-85.0, 0.00001, 0, 36.8, 0, -0.00001</GeoTransform>
<VRTRasterBand dataType="Float32" band="1"><NoDataValue>-32768</NoDataValue></VRTRasterBand></VRTDataset>''')
wgs84 = 'GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]]'
open(f'{t}/one.asc', 'w').write('ncols 1\nnrows 1\nxllcorner 9.0\nyllcorner 47.0\ncellsize 0.001\n5\n')
open(f'{t}/zeros.asc', 'w').write('ncols 200\nnrows 200\nxllcorner 9.0\nyllcorner 47.0\ncellsize 0.001\n' + ('0 ' * 200 + '\n') * 200)
for n in ('one', 'zeros'):
    open(f'{t}/{n}.prj', 'w').write(wgs84)
with open(f'{t}/big.csv', 'w') as f:  # 70 MB of sensor rows (10 million rows would be 200 MB)
    f.write('frame,compass_yaw_deg,inclinometer_pitch_deg,inclinometer_roll_deg\n')
    block = ''.join(f'{i},90.5,1.25,0.5\n' for i in range(100000))
    while f.tell() < 70 << 20:
        f.write(block)
PYEOF
"$BIN" render --dem "$JACKSBORO" --lat 36.52 --lon -84.16 --azimuth 200 --size 320x200 -o "$TMP/frame_0000.png" || fail "render"
# expect CODE PEAK_MB PATTERN COMMAND...: exit code, peak memory bound, message.
expect() {
  local code=$1 peak=$2 pattern=$3; shift 3
  /usr/bin/time -f "%M" -o "$TMP/mem" "$BIN" "$@" > /dev/null 2> "$TMP/err"
  local got=$?
  local kb; kb=$(tail -n 1 "$TMP/mem")
  [ "$got" -eq "$code" ] || fail "$* exited $got, expected $code: $(cat "$TMP/err")"
  [ -z "$pattern" ] || grep -q -- "$pattern" "$TMP/err" || fail "$*: stderr lacks '$pattern': $(cat "$TMP/err")"
  [ "$(grep -vc '^horizonreg' "$TMP/err")" -eq 0 ] || fail "$*: stderr has lines not ours: $(cat "$TMP/err")"
  [ "$kb" -le $((peak * 1024)) ] || fail "$*: peak memory $((kb / 1024)) MB above $peak MB"
  echo "ok ($((kb / 1024)) MB peak): $(head -c 150 "$TMP/err")"
}
expect 2 200 "30000 x 20000 = 600 million pixels" register "$TMP/huge.jpg" --dem "$JACKSBORO" --lat 36.52 --lon -84.16
expect 2 200 "more than the 1 million allowed" skyline "$TMP/huge.png" --max-image-mpx 1
expect 2 200 "more than 2048 MB allowed" horizon --dem "$TMP/huge.vrt" --lat 36.5 --lon -84.5
expect 2 200 "fewer than 2x2 posts" horizon --dem "$TMP/one.asc" --lat 47.0005 --lon 9.0005
expect 0 200 "" horizon --dem "$TMP/zeros.asc" --lat 47.1 --lon 9.1
expect 2 300 "more than the 64 MB" track "$TMP/frame_%04d.png" --dem "$JACKSBORO" --lat 36.52 --lon -84.16 --sensors "$TMP/big.csv"
# A JPEG with corrupt data: decoded, and libjpeg's own line comes back as our warning.
"$BIN" render --dem "$JACKSBORO" --lat 36.52 --lon -84.16 --azimuth 200 --size 640x400 -o "$TMP/view.jpg" || fail "render jpg"
python3 -c "
b = bytearray(open('$TMP/view.jpg', 'rb').read())
for i in range(3000, len(b) - 3000, 997): b[i] ^= 0x55
open('$TMP/corrupt.jpg', 'wb').write(b)"
expect 0 200 "warning: image: '$TMP/corrupt.jpg' was decoded with errors" skyline "$TMP/corrupt.jpg"
echo "PASS"
