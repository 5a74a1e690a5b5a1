#!/usr/bin/env bash
# check --framework torch from the installed wheel (issue 70, item 3): the wheel built from this
# checkout, installed by docs/canary.sh into a fresh venv in a scratch folder, with this checkout's
# .venv libraries lent offline (PYTHONPATH, PIP_NO_INDEX; as tests/test_check.py's recipe test), then
#   keras-rl check cartpole --framework torch --tier smoke
# Its report, picture and pip freeze are copied here.
#   bash results/checks/torch-from-wheel/run.sh
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../../.." && pwd)
scratch=$(mktemp -d)
site=$("$root/.venv/bin/python" -c 'import site; print(site.getsitepackages()[0])')
mkdir "$scratch/lent" "$scratch/job"
for entry in "$site"/*; do
  case "$(basename "$entry")" in keras_rl*|__editable__*keras_rl*|*keras_rl_repro*) ;; *) ln -s "$entry" "$scratch/lent/" ;; esac
done
"$root/.venv/bin/python" -m pip wheel -q --no-deps --no-build-isolation -w "$scratch/dist" "$root"
wheel=$(ls "$scratch"/dist/keras_rl_repro-*.whl)
cd "$scratch/job"
set +e
env -u VIRTUAL_ENV PYTHONPATH="$scratch/lent" PIP_NO_INDEX=1 KERAS_RL_WHEEL="$wheel[torch]" POSTS=cartpole TIER=smoke \
  FRAMEWORK=torch /usr/bin/time -v bash "$root/docs/canary.sh" > "$here/console.txt" 2> "$here/stderr.txt"
code=$?
set -e
cp check-runs/check.md check-runs/check.json pip-freeze.txt "$here/"
cp check-runs/cartpole/check.png "$here/check.png"
echo "exit $code" >> "$here/console.txt"
rm -rf "$scratch"
