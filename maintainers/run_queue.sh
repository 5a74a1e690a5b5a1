#!/usr/bin/env bash
# Long runs, one set after another, from a clean worktree at a committed version with a venv of
# its own (the shared .venv imports main's keras_rl, not the worktree's):
#
#   git worktree add ../wt-runs -b runs/NAME main && cd ../wt-runs && make install
#   nohup maintainers/run_queue.sh maintainers/queues/NAME.tsv > ../wt-runs.log 2>&1 &
#
# A queue file has one set per line: its folder, a tab, then `keras-rl` arguments without --out.
# Each set runs with --resume, is packed (keras-rl pack) and committed on the worktree's branch
# as it lands; merge the branch into main. Resumable: a set whose runs.parquet exists is skipped,
# an unfinished one resumes where it stopped. Refuses a dirty worktree (its seeds would record it).
# The seeds' weights and pictures, which git ignores, are moved to $RUN_QUEUE_EXTRAS
# (../run-queue-extras by default) before packing.
# Size a queue's sets to land within one working session: a session's worktree, and the seeds of
# a set that has not landed, do not outlive it (a long set runs as consecutive sets of its seeds).
set -euo pipefail
queue=${1:?usage: maintainers/run_queue.sh QUEUE_FILE}
extras=${RUN_QUEUE_EXTRAS:-../run-queue-extras}
if [[ ! -f "$queue" ]]; then echo "run_queue: no queue file $queue" >&2; exit 2; fi
if [[ -n "$(git status --porcelain --untracked-files=no)" ]]; then
  echo "run_queue: the worktree has uncommitted changes; long runs start from a committed version" >&2
  exit 2
fi
while IFS=$'\t' read -r -u 3 out args; do
  [[ -z "$out" || "$out" == \#* ]] && continue
  if git ls-files --error-unmatch "$out/runs.parquet" >/dev/null 2>&1; then
    echo "run_queue: $out is committed already"; continue
  fi
  if [[ -f "$out/runs.parquet" ]]; then  # packed, then stopped before its commit
    git add "$out" && git commit -q -m "long run landed: $out (keras-rl $args --resume --out $out)"
    continue
  fi
  echo "run_queue: $(date -u +%FT%TZ) starting $out"
  # shellcheck disable=SC2086  # the arguments are one line of plain words by design
  .venv/bin/keras-rl $args --resume --out "$out"
  # what git ignores in the seed folders (weights, checkpoints, pictures) is never committed and a
  # packed set does not keep it: moved, not deleted, under $extras
  git ls-files --others --ignored --exclude-standard -z "$out" | while IFS= read -r -d '' f; do
    mkdir -p "$extras/$(dirname "$f")" && mv "$f" "$extras/$f"
  done
  .venv/bin/keras-rl pack "$out"
  git add "$out"
  git commit -q -m "long run landed: $out (keras-rl $args --resume --out $out)"
  echo "run_queue: $(date -u +%FT%TZ) committed $out"
done 3< "$queue"
