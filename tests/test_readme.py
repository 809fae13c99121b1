import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_opens_with_the_two_commands():
    text = README.read_text()
    first = re.findall(r"```(?:bash|sh)\n(.*?)```", text, re.S)[0]
    assert "scripts/main.sh" in first and "scripts/test.sh" in first
    ci = (README.parent / ".ci" / "run").read_text()
    assert "scripts/test.sh" in ci


def test_readme_python_snippet_runs():
    """The GeReL snippet (the method modules' snippets run in tests/test_examples.py)."""
    snippet = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)[0]
    namespace: dict = {}
    exec(compile(snippet, "README.md", "exec"), namespace)
    metrics = namespace["metrics"]
    assert metrics["d_Theta"] < 0.61  # closer to the person's belief than the true dynamics are
    assert metrics["corr_R"] > 0.9 and metrics["d_pi"] < 0.1
