#!/usr/bin/env bash
# Steps per second of the whole loop with gsplat (docs/gpu.md, "The whole loop"), on a machine with CUDA and
# `pip install -e ".[cuda]"` done: gsplat build (timed), a 30-step warm-up in which numba compiles and caches
# its kernels, small-0 for 300 steps at two CPU thread counts (numba and torch), then small-0 (1000 steps)
# and medium-0 (2000 steps) at the faster one. Each run's summary goes to OUT/speed.log, its metrics to
# OUT/<run>.json.
#
#   bash benchmarks/gpu_speed.sh [OUT]          # about 7 minutes on one H100
#
# STEPS_SMALL / STEPS_MEDIUM shorten the two long runs; THREADS="16 4" sets the thread counts compared;
# BACKEND=numba times the CPU path the same way; EXTRA adds explore options to every timed run (e.g.
# EXTRA="--coverage.background False").
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-runs/gpu-speed}
mkdir -p "$OUT"
LOG="$OUT/speed.log"
T0=$(date +%s)
say() { echo "[$(( $(date +%s) - T0 )) s] $*" | tee -a "$LOG"; }
explore() {  # explore THREADS SCENE STEPS NAME
    say "explore $2 ($3 steps, $1 CPU threads)"
    NUMBA_NUM_THREADS=$1 OMP_NUM_THREADS=$1 python3 -m activesplat explore --scene "$2" --steps "$3" --seed 0 \
        --backend "${BACKEND:-gsplat}" --out "$OUT/$4" --overwrite --no-progress ${EXTRA:-} 2>&1 | tail -7 | tee -a "$LOG"
    cp "$OUT/$4/metrics.json" "$OUT/$4.json" 2>/dev/null
    python3 -c "import json; m = json.load(open('$OUT/$4.json')); print('mapper phases (ms/step)', \
{k: round(v, 1) for k, v in m.get('mapper_phases_ms', {}).items()}, \
'| rasterizer setup before the clock %.1f s' % m.get('backend_setup_s', float('nan')))" 2>/dev/null | tee -a "$LOG"
}
ms_per_step() { python3 -c "import json; print(json.load(open('$OUT/$1/metrics.json'))['ms_per_step'])"; }

nproc | tee -a "$LOG"
if [ "${BACKEND:-gsplat}" = gsplat ]; then
    nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader | tee -a "$LOG"
    say "gsplat build or cache load"
    ( time python3 -c "from gsplat.cuda._backend import _C" ) 2>&1 | grep real | tee -a "$LOG"
fi
say "warm-up"
python3 -m activesplat explore --scene small-0 --steps 30 --backend "${BACKEND:-gsplat}" --out "$OUT/warm-up" --overwrite \
    --no-progress > /dev/null 2>&1
best=""; best_ms=1e9
for threads in ${THREADS:-16 4}; do
    explore "$threads" small-0 300 "small-0-300-t$threads"
    ms=$(ms_per_step "small-0-300-t$threads")
    if python3 -c "import sys; sys.exit(not $ms < $best_ms)"; then best=$threads; best_ms=$ms; fi
done
say "faster thread count: $best ($best_ms ms/step over 300 steps)"
explore "$best" small-0 "${STEPS_SMALL:-1000}" small-0
[ "${STEPS_MEDIUM:-2000}" != 0 ] && explore "$best" medium-0 "${STEPS_MEDIUM:-2000}" medium-0  # 0: no medium run
say "done"
