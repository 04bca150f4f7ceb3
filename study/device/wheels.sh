#!/usr/bin/env bash
# The wheels a GPU machine without a package index needs to train and benchmark this project there
# (docs/gpu.md, "On a lent GPU machine"): what its image lacks, for its Python 3.12 on x86-64, at the
# versions this checkout's environment has, into .whl/ (git-ignored). The project itself travels as the
# working tree, run from its root.
#
#   bash study/device/wheels.sh            # then: du -sh .whl (the machine takes 64 MiB a call)
#
# There: python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl
#        export PYTHONPATH=/tmp/site
set -euo pipefail
cd "$(dirname "$0")/.."
rm -rf .whl && mkdir .whl
# What the image lacks (its torch, jax, numpy, scipy, absl, etils, cloudpickle, yaml, rich, tqdm,
# huggingface-hub stay): MuJoCo and MJX, Gymnasium, SB3, RL Zoo and the modules its utils import.
# Not mujoco-studio (13 MB: MuJoCo's viewer app, which `import mujoco` and the env do without): the
# working tree and the wheels travel together, 64 MiB at most.
packages=(mujoco mujoco-core mujoco-mjx glfw PyOpenGL trimesh gymnasium Farama-Notifications
          stable_baselines3 sb3_contrib rl_zoo3 sb3-team-hf-integration wasabi)
pinned=()
for name in "${packages[@]}"; do
    version=$(python -m pip show "$name" 2>/dev/null | awk '/^Version:/{print $2}')
    pinned+=("$name${version:+==$version}")
done
platforms=()
for tag in manylinux_2_39 manylinux_2_35 manylinux_2_34 manylinux_2_31 manylinux_2_28 manylinux_2_27 \
           manylinux_2_24 manylinux_2_17 manylinux2014 manylinux1; do
    platforms+=(--platform "${tag}_x86_64")
done
python -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
    "${platforms[@]}" -d .whl "${pinned[@]}"
du -sh .whl
