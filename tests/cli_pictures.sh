# cli_pictures.sh - `stf render` and `stf plot` end to end: a small run is rendered to PNG
# frames and plotted; the PNGs are valid (signature, IHDR size), a frame is not a uniform
# image, and an unreadable file exits 2.
#
# usage: bash cli_pictures.sh STF_BINARY PROJECT_DIR   (run in the build's tests directory)
. "$(dirname "$0")/lib_cli.sh" cli_pictures "$@"

PY=python3

# check_png FILE [W H]: a PNG (signature, IHDR), optionally of size W x H, whose pixels are
# not all the same (IDAT decompressed, filter bytes dropped, more than one distinct value).
check_png() {
    "$PY" - "$@" <<'PYEOF'
import struct, sys, zlib
path = sys.argv[1]
data = open(path, "rb").read()
if data[:8] != b"\x89PNG\r\n\x1a\n":
    sys.exit(f"{path}: not a PNG signature")
if data[12:16] != b"IHDR":
    sys.exit(f"{path}: no IHDR chunk first")
w, h, depth, ctype = struct.unpack(">IIBB", data[16:26])
if len(sys.argv) > 3 and (w, h) != (int(sys.argv[2]), int(sys.argv[3])):
    sys.exit(f"{path}: size {w}x{h}, expected {sys.argv[2]}x{sys.argv[3]}")
if w < 1 or h < 1 or depth != 8 or ctype != 2:
    sys.exit(f"{path}: unexpected IHDR {w}x{h} depth {depth} colour type {ctype}")
pos, idat = 8, b""
while pos < len(data):
    n, kind = struct.unpack(">I4s", data[pos:pos + 8])
    if kind == b"IDAT":
        idat += data[pos + 8:pos + 8 + n]
    pos += 12 + n
raw = zlib.decompress(idat)
stride = 1 + 3 * w
if len(raw) != stride * h:
    sys.exit(f"{path}: image data has {len(raw)} bytes, expected {stride * h}")
# undo the PNG filters to get the pixel values
prev, values = bytearray(stride - 1), set()
for y in range(h):
    f, line = raw[y * stride], bytearray(raw[y * stride + 1:(y + 1) * stride])
    for i in range(len(line)):
        a = line[i - 3] if i >= 3 else 0
        b = prev[i]
        c = prev[i - 3] if i >= 3 else 0
        if f == 1: line[i] = (line[i] + a) & 255
        elif f == 2: line[i] = (line[i] + b) & 255
        elif f == 3: line[i] = (line[i] + (a + b) // 2) & 255
        elif f == 4:
            p = a + b - c
            pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
            line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
    if y % 7 == 0:
        values.update(line)
    prev = line
if len(values) < 2:
    sys.exit(f"{path}: a uniform image")
PYEOF
}

"$STF" run "$PROJ/tests/scenes/small_drop.yaml" -o s.h5 --quiet --threads 1 >run.out 2>run.err
rc=$?
[ $rc -eq 0 ] || { fail "stf run exited $rc"; cat run.err >&2; exit 1; }

# render every third frame
"$STF" render s.h5 --every 3 -o frames >render.out 2>render.err
rc=$?
if [ $rc -ne 0 ]; then
    fail "stf render exited $rc"
    cat render.err >&2
else
    nframes=$(ls frames/frame_*.png 2>/dev/null | wc -l)
    [ "$nframes" -ge 2 ] || fail "stf render wrote $nframes frames"
    [ -f frames/frame_0000.png ] || fail "frames/frame_0000.png missing"
    for f in frames/frame_*.png; do
        [ -s "$f" ] || { fail "$f empty"; continue; }
        check_png "$f" 960 720 || fail "$f is not a valid picture"
    done
    size=$(wc -c <frames/frame_0001.png 2>/dev/null || echo 0)
    [ "$size" -gt 5000 ] || fail "frames/frame_0001.png only $size bytes"
fi

# montage of chosen frames
"$STF" render s.h5 --montage m.png --frames 0,3,6 --width 200 --height 160 >mont.out 2>mont.err
rc=$?
if [ $rc -ne 0 ]; then fail "stf render --montage exited $rc"; cat mont.err >&2
else check_png m.png || fail "m.png is not a valid picture"; fi
# -o with --montage: refused (exit 2), not silently ignored
"$STF" render s.h5 --montage m2.png -o mdir >mo.out 2>mo.err
rc=$?
[ $rc -eq 2 ] && grep -q "give one of them" mo.err && [ ! -e m2.png ] && [ ! -e mdir ] ||
    fail "stf render --montage with -o: exit $rc, want 2 and nothing written ($(cat mo.err))"

# speed colouring
"$STF" render s.h5 --frames 2 --color speed -o speed --width 320 --height 240 >sp.out 2>sp.err
rc=$?
if [ $rc -ne 0 ]; then fail "stf render --color speed exited $rc"; cat sp.err >&2
else check_png speed/frame_0000.png 320 240 || fail "speed/frame_0000.png invalid"; fi

# plot
"$STF" plot s.h5 -o p.png >plot.out 2>plot.err
rc=$?
if [ $rc -ne 0 ]; then fail "stf plot exited $rc"; cat plot.err >&2
else check_png p.png || fail "p.png is not a valid picture"; fi

# --color khist on a run without history: a note, not a silent one-colour picture
"$STF" run "$PROJ/tests/scenes/small_drop.yaml" -o nohist.h5 --quiet --threads 1 --duration 0.01 \
    --unset effects.history --unset effects.boundary_stick >nohist.out 2>&1 ||
    fail "stf run without history failed: $(tail -n 2 nohist.out)"
"$STF" render nohist.h5 --color khist -o nohist --frames 0 >nohist.rout 2>&1 ||
    fail "stf render --color khist without history failed: $(tail -n 2 nohist.rout)"
grep -q "note: the history stiffness is 0" nohist.rout ||
    fail "stf render --color khist without history says nothing: $(cat nohist.rout)"

# a cylinder is drawn with flat ends, not as a capsule: the same radius and length, held
# upright at t = 0, covers fewer rows of body colour as a cylinder than as a capsule (whose
# round ends reach a radius further each way)
for sh in cylinder capsule; do
    "$STF" run "$PROJ/tests/scenes/small_drop.yaml" -o "$sh.h5" --quiet --threads 1 --duration 0.01 \
        --set "bodies.0.shape=$sh" --set bodies.0.length=0.06 --set 'bodies.0.position=[0, 0, 0.14]' \
        >"$sh.out" 2>&1 || fail "stf run with a $sh failed: $(tail -n 2 "$sh.out")"
    "$STF" render "$sh.h5" -o "$sh" --frames 0 >"$sh.rout" 2>&1 || fail "stf render of the $sh failed"
done
if [ -s cylinder/frame_0000.png ] && [ -s capsule/frame_0000.png ]; then
    /usr/bin/python3 - cylinder/frame_0000.png capsule/frame_0000.png <<'PYEOF' || fail "cylinder against capsule"
import sys
from PIL import Image
def rows(path):  # rows holding a pixel of the body's red (r high, g and b low)
    im = Image.open(path).convert("RGB")
    w, h = im.size
    px = im.load()
    return sum(1 for y in range(h) if any(px[x, y][0] > 60 and px[x, y][0] > 2.5 * px[x, y][1]
                                          and px[x, y][0] > 2.5 * px[x, y][2] for x in range(w)))
c, k = rows(sys.argv[1]), rows(sys.argv[2])
print("body rows: cylinder %d, capsule %d" % (c, k))
if not (c > 0 and c < 0.9 * k):
    sys.exit("the cylinder (%d rows) is not shorter than the capsule (%d rows)" % (c, k))
PYEOF
fi

# bad input
"$STF" render /nonexistent.h5 >bad.out 2>bad.err
rc=$?
[ $rc -eq 2 ] || fail "stf render /nonexistent.h5 exited $rc, expected 2"
[ -s bad.err ] || fail "stf render /nonexistent.h5 printed no message"
"$STF" plot /nonexistent.h5 >bad2.out 2>bad2.err
rc=$?
[ $rc -eq 2 ] || fail "stf plot /nonexistent.h5 exited $rc, expected 2"
"$STF" render s.h5 --frames 5:x >bad3.out 2>bad3.err
rc=$?
[ $rc -eq 2 ] || fail "stf render --frames 5:x exited $rc, expected 2"
"$STF" plot s.h5 --body nosuchbody >bad4.out 2>bad4.err
rc=$?
[ $rc -eq 2 ] || fail "stf plot --body nosuchbody exited $rc, expected 2"

if [ $fails -ne 0 ]; then
    echo "cli_pictures: $fails failure(s)" >&2
    exit 1
fi
echo "cli_pictures: ok"
