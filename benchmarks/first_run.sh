#!/usr/bin/env bash
# The first run as a new user meets it: a fresh clone, `make serve`, and the time until the
# server answers its first POST /v1/act (install and zoo training included). Prints the phases'
# times; the server is stopped afterwards. Run it on an otherwise idle machine.
#   benchmarks/first_run.sh [REPO (default: this checkout)] [WORKDIR (default: a new temp dir)]
set -euo pipefail
repo=$(cd "${1:-$(dirname "$0")/..}" && pwd)
work=${2:-$(mktemp -d /tmp/coexist-first-run.XXXX)}
clone="$work/coexist"
git clone --quiet "$repo" "$clone"
cd "$clone"
body='{"env": "particle", "ego_goal": "a2", "observation": [0.1, 0.5, 0, 0, 0.7, 0.6, 0, 0],
       "partners": [{"index": 1, "goal": "b3"}], "seed": 7}'
ms() { echo $(( $(date +%s%N) / 1000000 )); }  # milliseconds since the epoch
seconds() { printf "%d.%03d" $(( $1 / 1000 )) $(( $1 % 1000 )); }
start=$(ms)
setsid make serve >"$work/serve.log" 2>&1 &
server=$!
trap 'kill -- -$server 2>/dev/null || true' EXIT
installed=""
while true; do
  now=$(ms)
  if [[ -z "$installed" && -f .venv/.installed-serve ]]; then
    installed=$(( now - start ))
    echo "installed after $(seconds $installed) s"
  fi
  if curl -sf -X POST 127.0.0.1:8000/v1/act -H 'content-type: application/json' -d "$body" \
      >"$work/first_act.json" 2>/dev/null; then
    break
  fi
  if ! kill -0 $server 2>/dev/null; then echo "make serve exited; see $work/serve.log"; exit 1; fi
  sleep 1
done
total=$(( $(ms) - start ))
echo "first /v1/act answered after $(seconds $total) s (training: $(seconds $(( total - ${installed:-0} ))) s)"
cat "$work/first_act.json"; echo
pkill -f "$clone/.venv/bin/coexist serve" || true
