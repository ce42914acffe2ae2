"""Gaussian RBF network (Zhang (2006) eq. 7.4-7.5), OLS training (Chen et al. 1991), its file."""

import json
import zipfile

import numpy as np
import pytest

from aero_dva.control.rbf_io import RBFFileError, load_rbf_network, save_rbf_network
from aero_dva.control.rbf_network import (
    SPECTRUM_INPUT_DIM,
    InputScaling,
    RBFNetwork,
    fit_input_scaling,
    select_spread,
    spectrum_input_names,
    spectrum_input_vector,
    train_rbf_ols,
)


def smooth(x):
    return np.sin(2 * np.pi * x[:, 0]) * np.cos(np.pi * x[:, 1]) + 3.0


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(0)
    x = rng.uniform(size=(400, 2))
    xv = rng.uniform(size=(300, 2))
    return x, smooth(x), xv, smooth(xv)


def test_ols_recovers_a_smooth_function(data):
    x, y, xv, yv = data
    result = train_rbf_ols(x, y, spread=0.3, tolerance=1e-6, max_neurons=80)
    error = result.network.predict(xv) - yv
    # Held-out error below 1 % of the target's spread (about 0.5).
    assert np.sqrt(np.mean(error**2)) < 0.01 * np.std(yv)
    assert result.network.n_neurons < 80  # it stopped on the tolerance, not the cap
    assert result.stop_reason == "tolerance"


def test_error_reduction_ratios_are_the_r_squared_of_the_selected_fit(data):
    x, y, _, _ = data
    result = train_rbf_ols(x, y, spread=0.2, tolerance=1e-9, max_neurons=25)
    err = result.error_reduction_ratios
    assert err.shape == (25,) and np.all(err >= 0)
    residual = result.network.predict(x) - y
    r_squared = 1 - np.sum(residual**2) / np.sum((y - y.mean()) ** 2)
    # Chen et al.: the ERRs of orthogonalised regressors add up to the explained fraction.
    assert err.sum() == pytest.approx(r_squared, abs=1e-9)
    assert result.unexplained_fraction == pytest.approx(1 - r_squared, abs=1e-9)
    assert result.training_rmse == pytest.approx(np.sqrt(np.mean(residual**2)), rel=1e-9)


def r_squared(columns, y):
    design = np.column_stack([np.ones(len(y)), *columns])
    residual = y - design @ np.linalg.lstsq(design, y, rcond=None)[0]
    return 1 - residual @ residual / np.sum((y - y.mean()) ** 2)


def test_each_step_picks_the_largest_error_reduction(data):
    x, y, _, _ = data
    x, y = x[:120], y[:120]
    result = train_rbf_ols(x, y, spread=0.2, tolerance=1e-9, max_neurons=2)
    net = result.network
    # Brute force over all candidates (the training inputs) with the same Gaussians.
    centres = net.scaling.apply(x)  # centres live in scaled input space
    columns = RBFNetwork(centres, np.zeros(120), 0.0, net.spread, net.scaling).hidden(x).T
    first = [r_squared([c], y) for c in columns]
    assert result.selected[0] == int(np.argmax(first))
    assert result.error_reduction_ratios[0] == pytest.approx(max(first), abs=1e-10)
    s0 = columns[result.selected[0]]
    second = [r_squared([s0, c], y) - max(first) for c in columns]
    second[result.selected[0]] = -1.0
    assert result.selected[1] == int(np.argmax(second))
    assert result.error_reduction_ratios[1] == pytest.approx(max(second), abs=1e-10)


def test_selection_finds_the_centre_of_a_single_bump():
    rng = np.random.default_rng(1)
    x = rng.uniform(size=(60, 3))
    scaling = InputScaling(np.zeros(3), np.ones(3))
    true = RBFNetwork(x[[17]], [5.0], 2.0, spread=0.4, scaling=scaling)
    y = true.predict(x)
    result = train_rbf_ols(x, y, spread=0.4, scaling=scaling, tolerance=1e-8)
    assert result.selected.tolist() == [17]
    assert result.error_reduction_ratios[0] == pytest.approx(1.0, abs=1e-12)
    assert result.network.output_weights[0] == pytest.approx(5.0, rel=1e-9)
    assert result.network.output_bias == pytest.approx(2.0, rel=1e-9)


def test_constant_target_needs_no_neurons():
    x = np.random.default_rng(2).uniform(size=(20, 2))
    result = train_rbf_ols(x, np.full(20, 7.5), spread=0.5)
    assert result.network.n_neurons == 0
    np.testing.assert_allclose(result.network.predict(x), 7.5)


def test_prediction_is_vectorised_and_accepts_one_sample(data):
    x, y, xv, _ = data
    net = train_rbf_ols(x, y, spread=0.3, max_neurons=20).network
    batch = net.predict(xv[:10])
    single = [net.predict(row) for row in xv[:10]]
    assert isinstance(single[0], float)
    np.testing.assert_allclose(batch, single, rtol=1e-12)
    with pytest.raises(ValueError, match="columns"):
        net.predict(np.zeros((3, 5)))


def test_hidden_layer_follows_eq_7_4_and_7_5():
    scaling = InputScaling([1.0, 0.0], [2.0, 1.0])
    net = RBFNetwork([[0.0, 0.0]], [1.0], 0.0, spread=0.5, scaling=scaling)
    p = np.array([2.0, 0.3])  # scaled: (0.5, 0.3)
    distance = np.hypot(0.5, 0.3)
    b = np.sqrt(np.log(2)) / 0.5
    assert net.hidden(p)[0, 0] == pytest.approx(np.exp(-((b * distance) ** 2)), rel=1e-12)
    # At distance == spread the response is 1/2.
    assert net.predict([2.0, 0.0]) == pytest.approx(0.5, rel=1e-12)


def test_input_scaling_makes_training_unit_independent(data):
    x, y, xv, _ = data
    factor = np.array([1000.0, 1e-3])  # e.g. c2 in N s/m next to a scaled spectrum
    a = train_rbf_ols(x, y, spread=0.3, max_neurons=30)
    b = train_rbf_ols(x * factor, y, spread=0.3, max_neurons=30)
    assert a.selected.tolist() == b.selected.tolist()
    np.testing.assert_allclose(a.network.predict(xv), b.network.predict(xv * factor), rtol=1e-8)
    scaling = fit_input_scaling(x * factor)
    np.testing.assert_allclose(scaling.apply(x * factor).min(axis=0), 0.0, atol=1e-12)
    np.testing.assert_allclose(scaling.apply(x * factor).max(axis=0), 1.0, atol=1e-12)


def test_spread_is_chosen_on_held_out_data(data):
    x, y, xv, yv = data
    selection = select_spread(x, y, xv, yv, [0.01, 0.3, 3.0], tolerance=1e-6, max_neurons=60)
    assert selection.best_spread == 0.3
    assert selection.validation_rmse[0] > 10 * selection.validation_rmse[1]
    assert selection.best.network.spread == 0.3


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"spread": 0.0}, ValueError, "spread"),
        ({"spread": "wide"}, TypeError, "spread"),
        ({"tolerance": 1.5}, ValueError, "tolerance"),
        ({"max_neurons": 0}, ValueError, "max_neurons"),
        ({"targets": np.zeros(3)}, ValueError, "targets"),
        ({"inputs": np.full((10, 2), np.nan)}, ValueError, "inputs"),
    ],
)
def test_training_arguments_are_validated(kwargs, error, match):
    args = {"inputs": np.zeros((10, 2)), "targets": np.zeros(10), "spread": 0.5, **kwargs}
    with pytest.raises(error, match=match):
        train_rbf_ols(**args)


def test_spectrum_inputs_have_the_study_layout():
    names, units = spectrum_input_names()
    assert len(names) == SPECTRUM_INPUT_DIM == 33
    assert names[0] == "plunge_5Hz" and names[16] == "pitch_5Hz" and names[-1] == "damping"
    assert units[-1] == "N s/m" and set(units[:-1]) == {"1"}
    magnitudes = np.arange(32.0).reshape(2, 16)
    vector = spectrum_input_vector(magnitudes, 1234.0)
    assert vector.shape == (33,) and vector[16] == 16.0 and vector[-1] == 1234.0


# ------------------------------------------------------------------------------------------
# File format
# ------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def network33():
    rng = np.random.default_rng(5)
    x = np.hstack([rng.dirichlet(np.ones(16), 120), rng.dirichlet(np.ones(16), 120)])
    x = np.hstack([x, rng.uniform(500, 3000, (120, 1))])
    y = 1000 + 500 * x[:, 3] + 0.2 * x[:, -1]
    names, units = spectrum_input_names()
    return train_rbf_ols(
        x, y, spread=0.8, max_neurons=15, input_names=names, input_units=units
    ).network, x


def test_save_load_round_trip(tmp_path, network33):
    net, x = network33
    path = save_rbf_network(net, tmp_path / "rbf", description="test")
    assert path.suffix == ".npz"
    loaded = load_rbf_network(path, expected_input_dim=33)
    np.testing.assert_array_equal(loaded.predict(x), net.predict(x))
    assert loaded.input_names == net.input_names and loaded.input_units == net.input_units
    assert loaded.spread == net.spread and loaded.output_unit == "N s/m"
    np.testing.assert_array_equal(loaded.scaling.offset, net.scaling.offset)
    # No pickle anywhere: the archive loads with pickle refused.
    with np.load(path, allow_pickle=False) as archive:
        assert json.loads(str(archive["header"]))["input_dim"] == 33


def test_wrong_input_dim_is_refused(tmp_path, network33):
    path = save_rbf_network(network33[0], tmp_path / "rbf.npz")
    with pytest.raises(RBFFileError, match="input_dim is 33, the controller needs 34"):
        load_rbf_network(path, expected_input_dim=34)


def rewrite(path, **changes):
    """Copy an archive's entries into a new one with some entries replaced."""
    with np.load(path, allow_pickle=False) as archive:
        entries = {k: archive[k] for k in archive.files}
    header = json.loads(str(entries["header"]))
    header.update(changes.pop("header", {}))
    entries["header"] = np.array(json.dumps(header))
    entries.update(changes)
    np.savez(path, **{k: v for k, v in entries.items() if v is not None})


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"centres": np.full((15, 33), np.nan)}, "'centres' contains NaN"),
        ({"centres": np.zeros((15, 32))}, r"'centres' has shape \(15, 32\)"),
        ({"output_weights": np.zeros(15, dtype=np.float32)}, "'output_weights' has dtype"),
        ({"output_weights": None}, "'output_weights' is missing"),
        ({"header": {"version": 99}}, "version 99"),
        ({"header": {"format": "other"}}, "format is 'other'"),
        ({"header": {"spread": -1.0}}, "spread must be within"),
        ({"header": {"input_names": ["a"]}}, "'input_names' must be 33 strings"),
        ({"header": {"input_scaling": {"offset": [0.0] * 33, "scale": [0.0] * 33}}}, "scale"),
    ],
)
def test_inconsistent_files_name_the_problem(tmp_path, network33, changes, match):
    path = save_rbf_network(network33[0], tmp_path / "rbf.npz")
    rewrite(path, **changes)
    with pytest.raises(RBFFileError, match=match) as info:
        load_rbf_network(path, expected_input_dim=33)
    assert str(path) in str(info.value)


def test_corrupted_and_missing_files(tmp_path, network33):
    path = save_rbf_network(network33[0], tmp_path / "rbf.npz")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(RBFFileError, match="rbf.npz"):
        load_rbf_network(path)
    path.write_bytes(b"not an archive at all")
    with pytest.raises(RBFFileError, match="not a readable .npz"):
        load_rbf_network(path)
    with pytest.raises(RBFFileError, match="no such file"):
        load_rbf_network(tmp_path / "missing.npz")


def test_object_arrays_are_refused_without_unpickling(tmp_path, network33):
    path = save_rbf_network(network33[0], tmp_path / "rbf.npz")
    rewrite(path, centres=np.array([object()] * 3, dtype=object))
    with pytest.raises(RBFFileError, match="without pickle"):
        load_rbf_network(path)
    assert zipfile.is_zipfile(path)
