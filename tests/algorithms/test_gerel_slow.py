"""Statistical "did it learn" checks at the scale of Table 1 (``pytest -m slow``)."""

import numpy as np
import pytest

from mindgap.experiments.table1 import Table1Config, fit_one, make_data


@pytest.mark.slow
@pytest.mark.parametrize("setting", ["reversed", "rotated"])
def test_gerel_beats_the_unaware_learners_on_grid7(setting):
    cfg = Table1Config()
    rows = {"gerel": [], "gerel-minus": [], "maxent-irl": []}
    for seed in range(3):
        task, rated, policy_demos, key = make_data(cfg, setting, seed, cfg.demos)
        for method in rows:
            row, _, _ = fit_one(cfg, method, "tied", task, rated, policy_demos, key, progress=False)
            rows[method].append(row)
    mean = {m: {k: np.mean([r[k] for r in rs]) for k in ("d_R", "d_Theta", "d_pi", "corr_R")} for m, rs in rows.items()}
    for other in ("gerel-minus", "maxent-irl"):
        for k in ("d_R", "d_Theta", "d_pi"):
            assert mean["gerel"][k] < mean[other][k], (other, k, mean)
        assert mean[other]["corr_R"] < 0
    assert mean["gerel"]["corr_R"] > 0.9
