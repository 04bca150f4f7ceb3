#!/usr/bin/env bash
# A chunk of one campaign entry's training on a lent machine (one GPU, 16 cores; docs/campaign.md, "On a
# GPU machine"), in one call of under 10 minutes: install the carried wheels (.whl/, from
# study/device/wheels.sh) where the interpreter lacks them, train the entry for MINUTES of wall time
# (it stops at a checkpoint and says so), then pack the entry's run folder, without its checkpoints/
# folder, previous checkpoint (.previous/), lock and failure note, as $OUT/run.tar beside the training log.
# The run folder has one writer at a time: stop the entry here before the call, and unpack the tar here
# before the campaign starts again.
#
#   bash study/device/campaign_chunk.sh ENTRY [MINUTES]   # there, from the repository root (default 8)
#   tar -xf <the call's files>/run.tar                         # here, from the repository root
#
# QUEUE (default runs/campaign.yml) names another queue file; PYTHON (default python3) another interpreter.
# The working tree and the wheels travel together, 64 MiB at most: move other run folders out of the tree
# for the call when the committed runs make it larger.
set -uo pipefail
cd "$(dirname "$0")/../.."
entry=${1:?usage: bash study/device/campaign_chunk.sh ENTRY [MINUTES]}
minutes=${2:-8}
queue=${QUEUE:-runs/campaign.yml}
python=${PYTHON:-python3}
out=${OUT:-device-chunk}
mkdir -p "$out"
if [ -d .whl ] && ! "$python" -c "import mujoco, stable_baselines3, rl_zoo3" 2>/dev/null; then
    "$python" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site \
        .whl/*.whl || exit 1
    export PYTHONPATH=/tmp/site:$PWD
fi
unset MUJOCO_GL  # no EGL libraries on the bare machine; nothing here renders
export PYTHONUNBUFFERED=1
run=$("$python" - "$queue" "$entry" <<'EOF'
import os
import sys

from study.campaign.queue import load_queue

queue, name = sys.argv[1:]
found = [entry for entry in load_queue(queue) if entry.name == name]
if not found:
    sys.exit(f"no entry named {name!r} in {queue}")
print(os.path.relpath(found[0].run))
EOF
) || exit 2
{ date -u; nproc; "$python" -c "import torch; print('torch', torch.__version__)"; } > "$out/machine.txt" 2>&1
"$python" -m study campaign --queue "$queue" --entry "$entry" --max-wall-minutes "$minutes" \
    > "$out/train.log" 2>&1
status=$?
tar -cf "$out/run.tar" --exclude=checkpoints --exclude=.previous --exclude=.lock --exclude=.failure.json "$run" || exit 3
tail -n 5 "$out/train.log"
# The entry's row of the status table: its steps now and its state (train: stopped at the wall-time limit,
# to go on from its checkpoint; done: trained and evaluated). The training's exit status is 0 only for done.
"$python" -m study campaign --queue "$queue" --status | grep -E "^(entry|$entry) "
echo "run folder $run packed into $out/run.tar (exit status of the training: $status)"
exit "$status"
