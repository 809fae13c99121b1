#!/usr/bin/env bash
# Set up .venv and run the main job: a quick end-to-end reproduction of Table 1.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/mindgap reproduce table1 --fast "$@"
