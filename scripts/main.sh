#!/usr/bin/env bash
# Set up .venv and run the main job: a quick end-to-end reproduction of Table 1, then the
# report of what it ran (runs/report/report.html beside the dissertation's numbers).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/mindgap reproduce table1 --fast --out runs/table1-fast "$@"
exec .venv/bin/mindgap report runs/table1-fast --out runs/report
