#!/usr/bin/env bash
# Snapshot of what the CLI writes, for checking that a refactor changes no output:
#   scripts/outputs_snapshot.sh OUT_DIR            (from the repository root, venv active)
#   ... change the code ...
#   scripts/outputs_snapshot.sh OUT_DIR2 && python scripts/compare_outputs.py OUT_DIR OUT_DIR2
# QUICK=1 runs only the three `run`s and two `video`s (~20 s); the full set (~2 min on 2 cores)
# adds the CI sweep + check, bench trackers, export + eval kitti and the scorecard CI subset.
# The frame cache goes to OUT_DIR/.cache, so every run renders afresh.
set -euo pipefail
OUT=$(realpath -m "$1")
rm -rf "$OUT"; mkdir -p "$OUT"
cd "$(dirname "${BASH_SOURCE[0]}")/.."
export PYOPENGL_PLATFORM=egl MONORARP_CACHE_DIR="$OUT/.cache"
M="python -m monorarp"
$M run scenarios/highway_cruise.yaml --frames 60 --no-video --out "$OUT/run_default" > "$OUT/run_default.txt"
$M run scenarios/lead_braking.yaml --frames 60 --detector oracle --oracle-jitter 1 --tracker sort --risk monte_carlo \
    --gps-speed --no-video --out "$OUT/run_mc" > "$OUT/run_mc.txt"
$M run scenarios/conditions/highway_vibration.yaml --frames 40 --horizon online --velocity difference --tracker bytetrack \
    --ego-speed lsd_period --refine-bottom off --warning-threshold 2.5 --out "$OUT/run_online" > "$OUT/run_online.txt"
$M video "$OUT/run_online/frames.mp4" --camera "$OUT/run_online/camera.json" --detector centernet --tracker kcf --risk monte_carlo --speed 25 \
    --horizon online --no-video --out "$OUT/video" > "$OUT/video.txt" 2>&1
$M video "$OUT/run_online/frames.mp4" --camera "$OUT/run_online/camera.json" --detector monorarp/models/centernet_vehicle.onnx \
    --ego-speed none --no-video --out "$OUT/video_onnx" > "$OUT/video_onnx.txt" 2>&1
if [ -n "${QUICK:-}" ]; then exit 0; fi
$M sweep scenarios/ci.yaml --out "$OUT/sweep" --cache off --no-progress > "$OUT/sweep.txt"
$M check "$OUT/sweep" --baseline results/baseline.json --failures-only > "$OUT/check.txt"
$M bench trackers --scenarios scenarios/static_single.yaml --trackers particle sort kcf --frames 15 --cache off \
    --out "$OUT/bench" > "$OUT/bench.txt" 2>&1
$M export "$OUT/run_online" --format kitti --out "$OUT/export_kitti" > "$OUT/export.txt" 2>&1
$M eval kitti "$OUT/export_kitti" --out "$OUT/eval_kitti" > "$OUT/eval.txt" 2>&1
$M scorecard --protocol scenarios/fcw/ci.yaml --out "$OUT/card" --no-progress > "$OUT/card.txt" 2>&1
