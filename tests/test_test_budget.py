"""scripts/test_budget.py: the suite's CPU time per test file held against the table in docs/development.md."""

import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("test_budget", ROOT / "scripts" / "test_budget.py")
tb = importlib.util.module_from_spec(spec)
spec.loader.exec_module(tb)


def test_the_table_round_trips_and_budgets_are_a_quarter_over_rounded_to_5_s(tmp_path):
    log = tmp_path / "log"
    lines = [{"file": "tests/a.py", "cpu_s": 10.0, "wall_s": 6}, {"file": "tests/b.py", "cpu_s": 1.0, "wall_s": 1}]
    log.write_text("".join(json.dumps(x) + "\n" for x in lines + [{"file": "tests/a.py", "cpu_s": 2.0, "wall_s": 1}]))
    times = tb.measured(log)
    assert times == {"tests/a.py": (12.0, 7.0), "tests/b.py": (1.0, 1.0)}
    doc = f"intro\n{tb.BEGIN}\n{tb.table(times)}\n{tb.END}\n"
    assert tb.budgets(doc) == {"tests/a.py": 15, "tests/b.py": 5}  # 12 × 1.25 = 15; 1.25 → 5


def test_the_committed_table_names_only_test_files_that_exist():
    budgets = tb.budgets((ROOT / "docs" / "development.md").read_text())
    assert budgets, "docs/development.md has no budget table"
    assert [f for f in budgets if not (ROOT / f).is_file()] == []
