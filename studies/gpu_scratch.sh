#!/usr/bin/env bash
# One GPU lease, prepared as one script: the functional env's throughput under gymnax's autoreset and
# under the optimistic one (float64 and float32, 4M and 16M vehicles), then two from-scratch runs of the
# progress recipe side by side, `rventry_agents/ppo_scratch_gpu.toml` (8,192 vehicles) and the same at
# 32,768 vehicles, each stopping after the chunk that ends past the time left. Every run's folder is
# then packed for evaluation on any machine:
#   python studies/ladder.py agent RUN --rungs nominal standard wide flight --json heldout.json
#
#   bash studies/gpu_scratch.sh OUTDIR [SECONDS]     (SECONDS: the whole script's budget, default 520)
#
# Needs the `jax` extra with a CUDA build of jaxlib. Where packages cannot be installed from an index,
# set WHEELS to a folder of wheels (gymnasium, gymnax, rejax and what they need): they are installed
# into a folder of their own, and the repository's root is put on the path (its rventry.egg-info,
# made by `pip install -e .`, names the commands).
set -u
OUT=${1:?an output folder}
TOTAL=${2:-520}
cd "$(dirname "$0")/.."
export PYTHONUNBUFFERED=1 XLA_PYTHON_CLIENT_PREALLOCATE=false
T0=$SECONDS
PY=${PYTHON:-python3}
if [ -n "${WHEELS:-}" ]; then
  $PY -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site "$WHEELS"/*.whl || exit 1
  export PYTHONPATH=/tmp/site:$PWD
fi
mkdir -p "$OUT" /tmp/gpu_scratch
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader || true
$PY -c "import jax, rejax, rventry_env; print('jax', jax.__version__, jax.devices())" || exit 1
echo "set up in $((SECONDS - T0)) s"
timeout 150 $PY benchmarks/jax_backend.py --skip accuracy speed numpy-substeps agreement ppo scratch sb3 \
  --functional-sizes 4194304 16777216 --functional-steps 100 --functional-resets 131072 \
  --json "$OUT/bench_functional.json" 2>&1 | grep -v "^[WI]1"
echo "throughput measured by $((SECONDS - T0)) s"
sed 's/^num_envs = 8192$/num_envs = 32768/; s/^resets = 256$/resets = 1024/; s/^chunk_timesteps = 67_108_864$/chunk_timesteps = 268_435_456/' \
  rventry_agents/ppo_scratch_gpu.toml > /tmp/gpu_scratch/e32768.toml
grep -q "^num_envs = 32768$" /tmp/gpu_scratch/e32768.toml && grep -q "^chunk_timesteps = 268_435_456$" /tmp/gpu_scratch/e32768.toml \
  || { echo "rventry_agents/ppo_scratch_gpu.toml no longer holds the lines the 32,768-vehicle variant changes"; exit 1; }
cp rventry_agents/ppo_scratch_gpu.toml /tmp/gpu_scratch/e8192.toml
BUDGET=$((TOTAL - (SECONDS - T0) - 50))  # the last chunk, the records and the packing after it
echo "each run stops after the chunk that ends past ${BUDGET} s; the two share the GPU"
for n in e8192 e32768; do
  $PY -m rventry_env.cli train ppo-scratch --config /tmp/gpu_scratch/$n.toml --out /tmp/gpu_scratch/$n \
    --max-wall-s "$BUDGET" > /tmp/gpu_scratch/$n.log 2>&1 &
done
wait
for n in e8192 e32768; do
  grep -v "^[WI]1" /tmp/gpu_scratch/$n.log | tail -n 25
  cp /tmp/gpu_scratch/$n.log /tmp/gpu_scratch/$n/train.log
  tar -C /tmp/gpu_scratch -czf "$OUT/$n.tgz" $n
done
echo "done in $((SECONDS - T0)) s"
