#!/usr/bin/env bash
# drive-bridge as a user installs it: build the wheel, install it in a fresh virtual environment
# outside the source tree, and run the simulated commissioning and a smoke test from there.
#   tools/check_wheel.sh            (from the repository root; CI runs it after the tests)
set -euo pipefail
repo="$(cd "$(dirname "$0")/.." && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
python3 -m pip wheel -q --no-deps -w "$work/dist" "$repo"
listing="$(python3 -m zipfile -l "$work"/dist/drive_bridge-*.whl)"
for f in drive_bridge/py.typed LICENSE drive_bridge/history/migrations/versions/0001_first.py; do   # typed package,
                                                          # licence, the history's migrations in the wheel
  grep -q "$f" <<< "$listing" || { echo "the wheel lacks $f" >&2; exit 1; }
done
python3 -m venv "$work/venv"
"$work/venv/bin/pip" install -q "$work"/dist/drive_bridge-*.whl
cd "$work"
export DRIVE_BRIDGE_VENDOR_EDS="${DRIVE_BRIDGE_VENDOR_EDS:-$repo/../shared/eds-vendor}"
export XDG_DATA_HOME="$work/data"                         # the history database of this check only
venv/bin/drive-bridge --help > /dev/null
venv/bin/drive-bridge scan --sim
venv/bin/drive-bridge commission --sim --campaign short --out run
venv/bin/python "$repo/tools/smoke_installed.py" run
# read whole first: grep -q leaving a pipe early makes the listing's next line a broken pipe
# (exit 1 under pipefail), a failure of this check that was not the package's
history="$(venv/bin/drive-bridge history list)"
grep -q "^1 run(s) in sqlite:///$work/data/drive-bridge/history.sqlite" <<< "$history" ||
  { echo "the installed commission kept no history" >&2; exit 1; }
echo "wheel check passed: $(ls dist)"
