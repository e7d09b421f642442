#!/usr/bin/env bash
# README figures: landing success on the Mars science mission over many seeds, with the
# low-altitude verification on vs off.
#
#   benchmarks/campaign_mars.sh                 # 200 seeds, all cores
#   RUNS=20 WORKERS=2 benchmarks/campaign_mars.sh
#   SCHEDULER=tcp://10.0.0.5:8786 benchmarks/campaign_mars.sh   # on a Dask cluster
#
# "Verification off" = verifying at the cruise altitude: every site already counts as
# verified where it was first detected, so the vehicle descends and lands without the
# low-altitude re-detection (and never bans a site). Override with VARY=KEY=SPEC if the
# mission schema grows an explicit switch. Interrupted? Run the same command again: the
# runs already in $OUT/runs.jsonl are skipped.
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
ON=$("$PY" -c "from autonomy.config import load_mission; import sys
print(load_mission(sys.argv[1]).landing.verification_altitude)" "$MISSION")
CRUISE=$("$PY" -c "from autonomy.config import load_mission; import sys
print(load_mission(sys.argv[1]).cruise_altitude)" "$MISSION")
VARY=${VARY:-landing.verification_altitude=$ON,$CRUISE}

args=(campaign "$MISSION" --runs "$RUNS" --seed "$SEED" --vary "$VARY" --out "$OUT")
[ -n "${WORKERS:-}" ] && args+=(--workers "$WORKERS")
[ -n "${SCHEDULER:-}" ] && args+=(--scheduler "$SCHEDULER")

echo "lander ${args[*]}" >&2
start=$(date +%s)
"$PY" -m autonomy "${args[@]}"
echo "wall time: $(( $(date +%s) - start )) s" >&2
