#!/usr/bin/env bash
# The canary in a CI job (docs/check.md, "The canary in your CI"): a fresh environment, the
# keras-rl-repro wheel, the release under test, then the check. Run it from an empty folder:
#
#   KERAS_RL_WHEEL=dist/keras_rl_repro-0.1.0-py3-none-any.whl UNDER_TEST="tensorflow==2.22.0rc0" bash canary.sh
#
# KERAS_RL_WHEEL  the wheel (built from a checkout: pip wheel --no-deps -w dist path/to/keras-rl-repro)
# UNDER_TEST      what to install over it: the release you are testing (empty: the pinned versions)
# POSTS           the posts to check (empty: all three)
# TIER            sensitive (default: twins, "the same bits" or a paired test), smoke or full
# FRAMEWORK       torch: the PyTorch rules (post 003 at the smoke tier, the default tier then); the wheel
#                 needs its torch extra: KERAS_RL_WHEEL="dist/keras_rl_repro-0.1.0-py3-none-any.whl[torch]"
# Exit code: the check's own. 0 consistent; 1 changed (fail the job); 2 usage; 3 no verdict (a seed
# crashed); 143 stopped. Keep check-runs/ as the job's artifact whatever the code: check.md (the
# verdicts and what changed around the code), check.json, and each post's check.png.
set -euo pipefail
: "${KERAS_RL_WHEEL:?set KERAS_RL_WHEEL to the keras-rl-repro wheel}"
python3 -m venv canary
canary/bin/pip install --quiet "$KERAS_RL_WHEEL"
if [ -n "${UNDER_TEST:-}" ]; then
  canary/bin/pip install --quiet $UNDER_TEST
fi
canary/bin/pip freeze > pip-freeze.txt  # what the check ran under, beside its report
if [ "${FRAMEWORK:-}" = torch ]; then default_tier=smoke; else default_tier=sensitive; fi
set +e
canary/bin/keras-rl check ${POSTS:-} --tier "${TIER:-$default_tier}" ${FRAMEWORK:+--framework "$FRAMEWORK"} \
  --no-progress --workers 2 --out check-runs
code=$?
set -e
echo "keras-rl check exited $code; the report is check-runs/check.md"
exit $code
