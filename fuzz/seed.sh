#!/usr/bin/env bash
# Seeds each fuzz target's corpus (fuzz/corpus/<target>/, not committed)
# from the repository's scenes and assets and from ../shared: robots'
# meshes and URDFs, sessions, and a recording cut short.
set -euo pipefail
cd "$(dirname "$0")"
shared=../../shared
seed() {
    local target=$1
    shift
    mkdir -p "corpus/$target"
    for f in "$@"; do
        [ -f "$f" ] && cp "$f" "corpus/$target/$(basename "$(dirname "$f")")_$(basename "$f")"
    done
    return 0
}
shopt -s nullglob globstar
seed stl "$shared"/robots/**/*.STL "$shared"/robots/**/*.stl
seed obj "$shared"/robots/**/*.obj
seed mesh_surface "$shared"/robots/**/*.obj
seed dae "$shared"/robots/**/*.dae
seed gltf ../assets/*.glb
seed urdf "$shared"/robots/**/*.urdf
seed scene ../scenes/*.json
seed session_json "$shared"/sessions/*.json
seed session_csv "$shared"/sessions/*.csv
seed ros_recording "$shared"/recordings/*.mcap "$shared"/recordings/*.bag
seed foxglove_readback "$shared"/recordings/*.mcap
mkdir -p corpus/settings corpus/mesh_surface corpus/calibration
# A calibration as `calibrate --out` writes it.
cat > corpus/calibration/lwr.calib.json <<'JSON'
{"format": "proprioscope-calibration", "version": 1, "robot": "lwr4plus",
 "joints": ["lwr_joint_1", "lwr_joint_2", "lwr_joint_3", "lwr_joint_4", "lwr_joint_5", "lwr_joint_6", "lwr_joint_7"],
 "observer_gain_per_s": 50.0,
 "coulomb_nm": [0.4, 0.5, 0.3, 0.4, 0.2, 0.2, 0.1], "viscous_nms_per_rad": [0.5, 0.5, 0.4, 0.4, 0.3, 0.3, 0.2],
 "offset_nm": [0.01, -0.02, 0.0, 0.03, 0.0, 0.0, 0.0], "sigma_nm": [0.02, 0.02, 0.02, 0.02, 0.02, 0.02, 0.02],
 "correlation_secs": [0.001, 0.001, 0.001, 0.001, 0.001, 0.001, 0.001],
 "rms_before_nm": [0.3, 0.4, 0.2, 0.3, 0.1, 0.1, 0.05], "rms_after_nm": [0.003, 0.003, 0.003, 0.003, 0.003, 0.003, 0.003],
 "frames_read": 2500, "free_frames": 960, "found": true}
JSON
# Settings: a link selector byte, then 18 little-endian f64s (q, point,
# force, σ, F min, F max, μ, α): ordinary values and the ranges' edges.
python3 - corpus/settings <<'PY'
import struct, sys
cases = {
    "ordinary": (3, [0.3, 0.6, -0.4, -1.2, 0.5, 0.9, 0.2, 0.1, 0.05, 0.6, -3, 2, -5, 0.05, 1, 30, 0.2, 0.5]),
    "edges": (0x85, [1e4, -1e4, 1e4, -1e4, 1e4, -1e4, 1e4, -1e3, 1e3, -1e3, 1e6, -1e6, 1e6, 1e-4, 0, 1e4, 2, 0.99]),
    "tiny": (1, [0] * 7 + [1e-300, 0, 0, 1e-300, 0, 0, 1e-4, 1e4, 1e4, 0, 0]),
}
for name, (selector, values) in cases.items():
    open(f"{sys.argv[1]}/{name}", "wb").write(bytes([selector]) + struct.pack("<18d", *values))
PY
# A press: link selector, σ, force range, μ, slide length, then 40 frames
# of (t, seven torques, seven angles, start); one that slides (torques
# that turn), one held, one whose times repeat and go back.
mkdir -p corpus/press
python3 - corpus/press <<'PY'
import math, struct, sys
def press(name, link, turn, times):
    values = [link, 0.05, 1.0, 30.0, 0.2, 0.003]
    for k, t in enumerate(times):
        a = turn * k / 40
        tau = [0.8 * math.cos(a + j) for j in range(7)]
        q = [0.3 * math.sin(0.5 * t + j) for j in range(7)]
        values += [t] + tau + q + [k * turn]
    open(f"{sys.argv[1]}/{name}", "wb").write(struct.pack(f"<{len(values)}d", *values))
press("slides", 4, 2.0, [0.01 * k for k in range(40)])
press("held", 5, 0.0, [0.01 * k for k in range(40)])
press("times", 3, 1.0, [0.01 * (k % 7) for k in range(40)])
PY
# A pair: σ, start sample, its force, μ, then a frame's seven torques and
# the next frame's (the pair carried into it).
mkdir -p corpus/pair
python3 - corpus/pair <<'PY'
import struct, sys
frame = [0.9, 1.2, -0.4, -1.1, 0.3, 0.25, -0.05]
later = [t * 0.9 for t in frame]
for name, mu in (("carried", 0.0), ("carried_friction", 0.2)):
    values = [0.05, 17.0, 12.0, mu] + frame + later
    open(f"{sys.argv[1]}/{name}", "wb").write(struct.pack(f"<{len(values)}d", *values))
PY
# Synthetic settings: a flags byte (1 observer, 2 motor side, 4 kinetic
# friction, 8 avoid covered, bits 4–5 contacts at once), then 24 f64s
# (seed, duration, rate, press, gap, force, ramp, slide, slowest slide,
# friction, bias, noise, motion, least torque, observer gain, mass and
# centre of mass error, joint friction, kinetic friction).
mkdir -p corpus/synth
python3 - corpus/synth <<'PY'
import struct, sys
base = [3.0, 2.0, 100.0, 0.3, 1.2, 0.3, 1.0, 5.0, 25.0, 0.05, 0.1, 0.02, 0.1, 0.01, 0.05, 0.2, 0.5,
        50.0, 0.08, 0.005, 0.2, 0.5, 0.3, 0.6]
cases = {"slides": 0x14, "observer": 0x13, "two": 0x2c, "plain": 0x10}
for name, flags in cases.items():
    open(f"{sys.argv[1]}/{name}", "wb").write(bytes([flags]) + struct.pack("<24d", *base))
PY
# A box, then one of its faces repeated; and a sliver and a giant.
{
    printf 'v 0 0 0\nv 0.1 0 0\nv 0.1 0.1 0\nv 0 0.1 0\nv 0 0 0.3\nv 0.1 0 0.3\nv 0.1 0.1 0.3\nv 0 0.1 0.3\n'
    printf 'f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n'
    for _ in $(seq 200); do printf 'f 1 3 2\n'; done
    printf 'v 1e30 0 0\nv 0 1e-30 0\nf 9 10 1\n'
} > corpus/mesh_surface/repeated_box.obj
mkdir -p corpus/rosmsg
# A definition (first byte: CDR), a NUL, a message byte and a CDR JointState.
printf '\x00std_msgs/Header header\nstring[] name\nfloat64[] position\n================\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n====\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n\x00\x00\x00\x01\x00\x00\x05\x00\x00\x00\x07\x00\x00\x00\x02\x00\x00\x00b\x00\x00\x00\x01\x00\x00\x00\x03\x00\x00\x00a1\x00\x00\x01\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf8\x3f' > corpus/rosmsg/joint_state
mkdir -p corpus/recording
for f in "$shared"/sessions/*.session.json; do
    # A recording as the app writes it: header line, one frame a line, cut.
    python3 - "$f" corpus/recording/"$(basename "$f")" <<'PY' || true
import json, sys
s = json.load(open(sys.argv[1]))
frames = s.pop("frames")[:20]
head = json.dumps(s)[:-1] + ',"frames":['
lines = [head] + [json.dumps(fr) + ("," if i + 1 < len(frames) else "") for i, fr in enumerate(frames)]
text = "\n".join(lines)
open(sys.argv[2], "w").write(text[: len(text) * 2 // 3])
PY
done
mkdir -p corpus/live
for f in "$shared"/sessions/*.session.json; do
    # A live stream: a header line, then a frame a line.
    python3 - "$f" corpus/live/"$(basename "$f")" <<'PY' || true
import json, sys
s = json.load(open(sys.argv[1]))
frames = s.pop("frames")[:20]
lines = [json.dumps(s)] + [json.dumps(fr) for fr in frames]
open(sys.argv[2], "w").write("\n".join(lines) + "\n")
PY
done
