#!/usr/bin/env bash
# Does `pip install -e .` keep a TensorFlow the user already has? A fresh venv gets TensorFlow
# 2.19.1 first, then this project; the versions before and after, and a 3-episode run, go to
# results/compat/keep-tf2.19.1.md.
#     bash matrix/compat_keep_tf.sh [TF_VERSION]
set -euo pipefail
cd "$(dirname "$0")/.."
tf=${1:-2.19.1}
venv=$(mktemp -d)/venv
out=results/compat/keep-tf$tf.md
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet "tensorflow==$tf"
before=$("$venv/bin/pip" freeze | grep -iE '^(tensorflow|keras|numpy)==' | tr '\n' ' ')
"$venv/bin/pip" install --quiet -e .
after=$("$venv/bin/pip" freeze | grep -iE '^(tensorflow|keras|numpy|gymnasium)==' | tr '\n' ' ')
run=$(mktemp -d)
code=0
(cd "$run" && "$venv/bin/keras-rl" reproduce pendulum --seeds 0 --episodes 3 --no-progress --out "$run/out" > "$run/log" 2>&1) || code=$?
rows=$(($(wc -l < "$run/out/seed_0/episodes.csv") - 1))
status=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['status'])" "$run/out/seed_0/summary.json")
tmp=$(mktemp)
cat > "$tmp" <<MD
# \`pip install -e .\` over an installed TensorFlow $tf

Made by \`bash matrix/compat_keep_tf.sh $tf\` on $(date -u +%Y-%m-%d).

- Before: $before
- After \`pip install -e .\`: $after
- \`keras-rl reproduce pendulum --seeds 0 --episodes 3\` there: exit $code (1: the post's criterion is not met in 3 episodes, as expected), run status \`$status\`, $rows episodes in \`episodes.csv\`.
MD
mkdir -p "$(dirname "$out")"
mv "$tmp" "$out"
cat "$out"
