#!/usr/bin/env bash
# Set up .venv and run the lint and the default (fast) test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# The study app's browser test drives the system's Chromium (headless), installed from the
# system's packages when missing; Playwright never downloads a browser. Without apt-get the
# test is skipped and says why.
if ! command -v chromium >/dev/null 2>&1 && ! command -v chromium-browser >/dev/null 2>&1; then
  if command -v apt-get >/dev/null 2>&1; then
    sudo=""
    if [[ "$(id -u)" != 0 ]] && command -v sudo >/dev/null 2>&1; then sudo="sudo -n"; fi
    $sudo apt-get install -y -qq chromium >/dev/null 2>&1 \
      || { $sudo apt-get update -qq && $sudo apt-get install -y -qq chromium >/dev/null; } \
      || echo "scripts/test.sh: could not install chromium; the browser test will be skipped" >&2
  else
    echo "scripts/test.sh: no apt-get to install chromium; the browser test will be skipped" >&2
  fi
fi
# `--slow` runs the slow tier instead: the statistical "did it learn" checks (tests marked
# slow; docs/development.md lists them with their runtimes).
marker=()
if [[ "${1:-}" == "--slow" ]]; then
  shift
  marker=(-m slow)
else
  # The default suite's time is mostly XLA compiling programs that then run for a moment: LLVM
  # at optimisation level 1 and XLA's older CPU fusion emitters compile them in less time
  # (measured: 13:52 -> 10:19 cold, 4:29 -> 5:00 warm; docs/development.md). The slow tier, whose
  # programs run for minutes, and every run outside the tests keep XLA's defaults. Flags set in
  # XLA_FLAGS come after these and win.
  export XLA_FLAGS="--xla_backend_optimization_level=1 --xla_cpu_use_fusion_emitters=false ${XLA_FLAGS:-}"
fi
.venv/bin/ruff check src tests benchmarks
# Two test processes (pytest-xdist): most of the suite's time is XLA compiling, one core each.
# A file's tests stay in one process (--dist loadfile), so those built on one configuration
# compile it once.
# The suite's CPU time (user + system of every test process) is printed at the end: the default
# tier's budget is kept in CPU-minutes (docs/development.md), so a change that costs more shows
# in its own run.
cpu_log=$(mktemp)
children_cpu() {  # seconds of CPU used by this shell's finished children (`times` in this shell, not a subshell)
  times > "$cpu_log"
  tail -n 1 "$cpu_log" | awk '{ s = 0; for (i = 1; i <= 2; i++) { split($i, t, "m"); sub("s", "", t[2]); s += t[1] * 60 + t[2] }; print s }'
}
# Each test file's CPU time goes to a log (tests/conftest.py), held against the budget per file in
# docs/development.md by scripts/test_budget.py: a file that costs more than its budget is named.
own_log=""
if [[ -z "${MINDGAP_TEST_CPU_LOG:-}" ]]; then own_log=1; MINDGAP_TEST_CPU_LOG=$(mktemp); fi
export MINDGAP_TEST_CPU_LOG
children_cpu > "$cpu_log.before"
status=0
.venv/bin/python -m pytest -n "${MINDGAP_TEST_WORKERS:-2}" --dist loadfile "${marker[@]}" "$@" || status=$?
children_cpu > "$cpu_log.after"
if [[ ${#marker[@]} -eq 0 ]]; then .venv/bin/python scripts/test_budget.py "$MINDGAP_TEST_CPU_LOG" || true; fi
awk -v a="$(cat "$cpu_log.before")" -v b="$(cat "$cpu_log.after")" \
  'BEGIN { printf "scripts/test.sh: the tests took %.1f CPU-minutes\n", (b - a) / 60 }'
rm -f "$cpu_log" "$cpu_log.before" "$cpu_log.after"
if [[ -n "$own_log" ]]; then rm -f "$MINDGAP_TEST_CPU_LOG"; fi
exit "$status"
