#!/usr/bin/env bash
# README figures: landing success on the Mars science mission over many seeds, with the
# low-altitude verification on vs off.
#
#   benchmarks/campaign_mars.sh                 # 200 seeds, all cores
#   RUNS=20 WORKERS=2 benchmarks/campaign_mars.sh
#   SCHEDULER=tcp://SCHEDULER_HOST:8786 benchmarks/campaign_mars.sh   # on a Dask cluster
#
# The two variants are landing.verify=true (the thesis procedure: re-detect the site from
# 2.5 m before landing, ban it otherwise) and landing.verify=false (land after the blind
# descent). Override with VARY=KEY=SPEC. Interrupted? Run the same command again: the runs
# already in $OUT/runs.jsonl are skipped.
set -euo pipefail
cd "$(dirname "$0")/.."

MISSION=${MISSION:-missions/mars_science.yaml}
RUNS=${RUNS:-200}
SEED=${SEED:-2024}
OUT=${OUT:-campaigns/mars_verification}
PY=${PY:-.venv/bin/python}

if [ ! -f "$MISSION" ]; then
  echo "campaign_mars.sh: $MISSION not found (set MISSION=...)" >&2
  exit 2
fi
VARY=${VARY:-landing.verify=true,false}

args=(campaign "$MISSION" --runs "$RUNS" --seed "$SEED" --vary "$VARY" --out "$OUT")
[ -n "${WORKERS:-}" ] && args+=(--workers "$WORKERS")
[ -n "${SCHEDULER:-}" ] && args+=(--scheduler "$SCHEDULER")

echo "lander ${args[*]}" >&2
start=$(date +%s)
"$PY" -m autonomy "${args[@]}"
echo "wall time: $(( $(date +%s) - start )) s" >&2
