import csv
from dataclasses import replace

import pytest

from mindgap.experiments import coffee


@pytest.mark.slow
def test_study_with_both_belief_parameterisations(tmp_path):
    cfg = replace(coffee.preset("fast"), belief_params=("factored", "per-sa"))
    summary = coffee.run(cfg, tmp_path, progress=False)
    with (tmp_path / "results.csv").open() as f:
        rows = list(csv.DictReader(f))
    per_sa = [r for r in rows if r["belief_param"] == "per-sa"]
    assert len(per_sa) == 2 * cfg.participants and all(r["method"] == "gerel" for r in per_sa)
    assert all(0.0 < float(r["spill_learned"]) < 1.0 for r in per_sa)
    assert {"GeReL (factored)", "GeReL (per-sa)", "GeReL⁻"} <= set(summary["learned"])
    assert "spill" in summary["correlations"]["GeReL (per-sa)"]
