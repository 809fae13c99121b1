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


def test_the_machine_s_pace_is_the_median_ratio_and_only_files_past_it_grew(tmp_path, capsys, monkeypatch):
    rows = {f"tests/f{i}.py": 20.0 for i in range(6)}
    doc = f"{tb.BEGIN}\n" + tb.table({f: (t, t) for f, t in rows.items()}) + f"\n{tb.END}\n"
    assert tb.measured_column(doc) == rows
    # a machine 1.5 times slower on every file, and one file that also doubled
    times = {f: (30.0, 30.0) for f in rows} | {"tests/f0.py": (60.0, 60.0)}
    assert tb.pace(times, rows) == 1.5
    assert tb.pace({"tests/f0.py": (1.0, 1.0)}, rows) is None  # too few files to judge a pace
    (tmp_path / "development.md").write_text(doc)
    log = tmp_path / "log"
    log.write_text("".join(json.dumps({"file": f, "cpu_s": c, "wall_s": w}) + "\n" for f, (c, w) in times.items()))
    monkeypatch.setattr(tb, "DOC", tmp_path / "development.md")
    monkeypatch.setattr("sys.argv", ["test_budget.py", str(log)])
    assert tb.main() == 0
    out = capsys.readouterr().out
    assert "tests/f0.py took 60 CPU-s, over its budget of 25 and of 38 at this machine's pace" in out
    assert "tests/f1.py took 30 CPU-s, over its budget of 25 (38 at this machine's pace)" in out
    assert "6 over budget (1 also at this machine's pace)" in out and "pace: 1.50 times" in out
