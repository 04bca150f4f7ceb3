#!/usr/bin/env bash
# The robust recipe's speed on a lent GPU machine (one GPU, 16 cores), in one call of under 10 minutes:
# MJX on the GPU at 4096 robots (raw physics, the env and its parts, SB3 PPO and HuRiPPO end to end, a
# profile of one HuRiPPO update; 16384 robots with GPU_LARGE_S set), then the CPU backend on all cores
# (networks on the CPU, then on the GPU) and on 2 of them, side by side on the same machine, with the
# update size of the 32 x 512 recipe. Each part has its own time limit, so one that
# overruns leaves the others' figures. Logs go to $OUT (or ./device-figures when OUT is unset). About 8.5
# minutes in all with the default limits: run it with the device tool's timeout_s 560, carrying .whl.
#
#   bash study/device/wheels.sh          # here, once: the wheels the machine lacks, into .whl/
#   bash study/device/figures.sh         # there, from the repository root, with .whl carried
#                                             # (and .jax-cache.tgz, where an earlier call left one)
#
# The working tree and the wheels travel together, 64 MiB at most: when the committed runs make it larger,
# move finished runs' folders out of the tree for the call.
set -uo pipefail
cd "$(dirname "$0")/.."
out=${OUT:-device-figures}
mkdir -p "$out"
if [ -d .whl ]; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site \
        .whl/*.whl || exit 1
    export PYTHONPATH=/tmp/site:$PWD
fi
unset MUJOCO_GL  # no EGL libraries on the bare machine; nothing here renders
export PYTHONUNBUFFERED=1 JAX_COMPILATION_CACHE_DIR=/tmp/jax-cache
# JAX's compiled functions from an earlier call (its $OUT/jax-cache.tgz, saved here as .jax-cache.tgz and
# carried): a machine of the same kind and versions skips the minutes of compiling for unchanged code.
mkdir -p /tmp/jax-cache
[ -f .jax-cache.tgz ] && tar xzf .jax-cache.tgz -C /tmp/jax-cache
{ date -u; nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader; nproc;
  python3 -c "import jax, torch, mujoco; print('jax', jax.__version__, 'torch', torch.__version__, 'mujoco', mujoco.__version__)"; } \
    2>&1 | tee "$out/machine.txt"
robust=(--conf-file hyperparams/huri_robust.yml)
gpu_robots=${GPU_ROBOTS:-4096}         # smaller for a trial run of this script on a CPU
read -r -a cpu_robots <<< "${CPU_ROBOTS:-32 256 1024}"
section() { echo "=== $1 ($(date -u +%T))"; }
# The first compile of the env's functions on the GPU takes minutes (over 165 s at 4096 robots on an H100,
# 2026-11-27); JAX_COMPILATION_CACHE_DIR keeps them for the next process on the same machine only.
{
    section "MJX, $gpu_robots robots x 32 steps"
    timeout -k 10 "${GPU_SMALL_S:-280}" python3 benchmarks/bench_mjx.py "${robust[@]}" --n-steps 32 --num-envs "$gpu_robots" \
        --iterations 2 --steps 10 --split --profile
} 2>&1 | grep -v -e "^USDT" -e "warp" | tee "$out/gpu.txt"
{
    section "CPU backend, all cores, 16384 samples per update"
    timeout -k 10 "${CPU_ALL_S:-90}" python3 benchmarks/bench_training.py "${robust[@]}" --num-envs "${cpu_robots[@]}" \
        --samples-per-update 16384 --algos huri-baseline huri --iterations 2
    section "CPU backend, all cores, the networks on the GPU"
    timeout -k 10 "${CPU_GPU_S:-60}" python3 benchmarks/bench_training.py "${robust[@]}" --num-envs "${cpu_robots[-1]}" \
        --samples-per-update 16384 --algos huri-baseline huri --iterations 2 --device cuda
    section "CPU backend, 2 cores (taskset), the 32 x 512 recipe"
    timeout -k 10 "${CPU_TWO_S:-55}" taskset -c 0,1 python3 benchmarks/bench_training.py "${robust[@]}" --num-envs 32 \
        --algos huri-baseline huri --iterations 2
} 2>&1 | tee "$out/cpu.txt"
[ "${GPU_LARGE_S:-0}" -gt 0 ] && {  # its compile takes minutes more: only where asked (GPU_LARGE_S=...)
    section "MJX, 16384 robots x 32 steps"
    timeout -k 10 "$GPU_LARGE_S" python3 benchmarks/bench_mjx.py "${robust[@]}" --n-steps 32 --num-envs 16384 \
        --iterations 2 --steps 10 --split
} 2>&1 | grep -v -e "^USDT" -e "warp" | tee "$out/gpu_large.txt"
tar czf "$out/jax-cache.tgz" -C /tmp/jax-cache . && [ "$(stat -c %s "$out/jax-cache.tgz")" -le 16000000 ] \
    || rm -f "$out/jax-cache.tgz"  # what comes back: 16 MB a file at most
section "done"
