"""Checks shared by the domain tests."""
from dataclasses import replace

import numpy as np
import pytest

from dva_offline.discrepancy import loop
from dva_offline.discrepancy.fitting import ModelSpec, fit_model, holdout_split


def batch_rows_equal_predict(dom) -> int:
    """Every spec the loop fits (baseline and candidates): batch_predict row by row equals
    predict, to the bit, and the fit with the batched Jacobian matches scipy's 2-point one."""
    split = holdout_split(dom.observations.groups)
    base_spec = dom.baseline(split.train)
    base = fit_model(base_spec, dom.observations, split)
    specs = [base_spec, *[s for s in dom.candidates(base, loop._features(dom.observations, base))
                          if isinstance(s, ModelSpec)]]
    rng = np.random.default_rng(1)
    for spec in specs:
        v0 = np.array([p.initial for p in spec.params])
        rows = v0 * (1 + 0.01 * rng.standard_normal((4, v0.size)))
        batch = spec.batch_predict(rows)
        assert batch.shape == (4, dom.observations.values.size), spec.name
        for row, values in zip(rows, batch):
            np.testing.assert_array_equal(values, spec.predict(row), err_msg=spec.name)
    plain = fit_model(replace(base_spec, batch_predict=None), dom.observations, split)
    assert base.error == pytest.approx(plain.error, rel=1e-6)
    return len(specs)

