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
seed dae "$shared"/robots/**/*.dae
seed gltf ../assets/*.glb
seed urdf "$shared"/robots/**/*.urdf
seed scene ../scenes/*.json
seed session_json "$shared"/sessions/*.json
seed session_csv "$shared"/sessions/*.csv
seed ros_recording "$shared"/recordings/*.mcap "$shared"/recordings/*.bag
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
