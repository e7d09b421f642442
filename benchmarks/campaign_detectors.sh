#!/usr/bin/env bash
# README figures: the three perception detectors in the loop. The demo mission over the
# urban world (buildings, trees, roads), each detector the only source of sites, on the same
# seeds; landings judged by the ground truth.
#
#   benchmarks/campaign_detectors.sh                    # 40 seeds per detector, all cores
#   RUNS=10 WORKERS=2 benchmarks/campaign_detectors.sh
#
# Interrupted? Run the same command again: the runs already in $OUT/runs.jsonl are skipped.
set -euo pipefail
cd "$(dirname "$0")/.."

MISSION=${MISSION:-missions/demo.yaml}
RUNS=${RUNS:-40}
SEED=${SEED:-2026}
OUT=${OUT:-campaigns/detectors_urban}
PY=${PY:-.venv/bin/python}
WORLD=${WORLD:-urban}
DETECTORS=${DETECTORS:-elevation_map,lidar_pca,depth_costmap}

if [ ! -f "$MISSION" ]; then
  echo "campaign_detectors.sh: $MISSION not found (set MISSION=...)" >&2
  exit 2
fi

args=(campaign "$MISSION" --runs "$RUNS" --seed "$SEED" --vary "world.kind=$WORLD"
      --vary "perception.detector=$DETECTORS" --out "$OUT")
[ -n "${WORKERS:-}" ] && args+=(--workers "$WORKERS")

echo "lander ${args[*]}" >&2
start=$(date +%s)
"$PY" -m autonomy "${args[@]}"
echo "wall time: $(( $(date +%s) - start )) s" >&2
