"""Which covariate names are excitation levels."""
import pytest

from dva_offline.discrepancy.covariate_kinds import is_level


@pytest.mark.parametrize("name", ["excitation_n", "force_rms", "Voltage [V]", "amp_g",
                                  "Force (N)", "level", "drive_mv"])
def test_levels(name):
    assert is_level(name)


@pytest.mark.parametrize("name", ["temperature_c", "T", "temp_k", "pressure_bar", "set",
                                  "humidity", ""])
def test_not_levels(name):
    assert not is_level(name)
