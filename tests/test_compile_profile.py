"""scripts/compile_profile.py: JAX's compile events per test, logged by the plugin and summed by the script."""

import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("compile_profile", ROOT / "scripts" / "compile_profile.py")
cp = importlib.util.module_from_spec(spec)
spec.loader.exec_module(cp)


def test_events_between_a_test_s_start_and_finish_are_logged_per_function(tmp_path, monkeypatch):
    log = tmp_path / "log"
    monkeypatch.setenv("MINDGAP_COMPILE_LOG", str(log))
    cp._listen("/jax/core/compile/backend_compile_duration", 9.0, fun_name="jit(f)")  # before any test: ignored
    cp.pytest_runtest_logstart("tests/a.py::t", None)
    cp._listen("/jax/core/compile/jaxpr_trace_duration", 0.5, fun_name="f")
    cp._listen("/jax/core/compile/jaxpr_to_mlir_module_duration", 0.25, fun_name="jit(f)")
    cp._listen("/jax/core/compile/backend_compile_duration", 2.0, fun_name="jit(f)")
    cp._listen("/jax/core/compile/backend_compile_duration", 1.0, fun_name="jit(f)")
    cp._listen("/jax/some/other/event", 5.0, fun_name="jit(g)")
    cp.pytest_runtest_logfinish("tests/a.py::t", None)
    cp._listen("/jax/core/compile/backend_compile_duration", 9.0, fun_name="jit(f)")  # after it: ignored
    (line,) = log.read_text().splitlines()
    assert json.loads(line) == {
        "test": "tests/a.py::t",
        "funs": {"f": {"trace": 0.5, "lower": 0.25, "compile": 3.0, "programs": 2}},
    }


def test_the_summary_ranks_functions_and_tests_by_their_seconds(tmp_path, capsys):
    log = tmp_path / "log"
    rows = [
        {"test": "tests/a.py::t1", "funs": {"f": {"trace": 1.0, "lower": 1.0, "compile": 8.0, "programs": 1}}},
        {"test": "tests/b.py::t2", "funs": {"f": {"trace": 0.0, "lower": 0.0, "compile": 2.0, "programs": 1},
                                             "g": {"trace": 0.0, "lower": 0.0, "compile": 1.0, "programs": 3}}},
    ]  # fmt: skip
    log.write_text("".join(json.dumps(r) + "\n" for r in rows))
    cp.summary(str(log), top=5)
    out = capsys.readouterr().out.splitlines()
    assert "2 tests, 13 s" in out[0]
    funs = [line.split() for line in out if line.endswith(("  f", "  g"))]
    assert funs == [["12.0", "s", "2", "programs", "2", "files", "f"], ["1.0", "s", "3", "programs", "1", "files", "g"]]
    assert [line.split()[-1] for line in out if "tests/" in line] == ["tests/a.py::t1", "tests/b.py::t2"]
