"""Test flights that hide one plant effect (the generator of the flight-domain tests).

Not used by the loop. A case is a stepped flight of the reference wing recorded through the
batch path (:func:`aero_dva.bag.runtime_recording.record_runtime`) into an MCAP bag, flown
with a hidden plant (:mod:`aero_dva.flight.hidden_plant`) that the log does not reveal:

- three airspeeds drawn in 0.55-0.85 U_cr, flown in a random order and then again in the same
  order; at each visit a low c2 (100-300 N s/m) and a high c2 (900-1500 N s/m) are held for
  ``dwell`` s each (12 dwells, 11 c2 steps);
- the aileron force (1 kN RMS) alternates between level 1 and level 3 every airspeed visit, so
  response level, airspeed, c2 and time are not confounded;
- accelerometer noise, white, RMS 1-4 % of each channel's typical level at 1 kN;
- one hidden effect with a random magnitude above the detectability threshold of
  :data:`THRESHOLDS`.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

LIBRARY_EFFECTS = ("actuator_lag", "sensor_delay", "cubic_stiffness", "unsteady_aero",
                   "parameter_drift")
OUTSIDE_EFFECTS = ("sensor_gain",)
THRESHOLDS = {
    "actuator_lag": "time constant T 0.5-1.5 s (c2 steps every dwell)",
    "sensor_delay": "delay 1-10 ms (whole samples at 1 kHz)",
    "cubic_stiffness": "3 kappa sigma_alpha^2 = 15-40 % at the high excitation level "
                       "(kappa from the nominal pitch RMS 1.2e-3 rad there)",
    "unsteady_aero": "Jones lag amplitudes x 0.2-1.2",
    "parameter_drift": "the DVA spring k1 changes by 10-25 % over the flight (either sign)",
    "sensor_gain": "one accelerometer's gain off by 5-15 % (either sign): outside the library",
}
ACC_RMS = (1.0, 1.8, 1.9)  # typical accelerometer RMS at 1 kN [m/s^2, rad/s^2, m/s^2]
PITCH_RMS_HIGH = 1.2e-3  # [rad] typical pitch RMS at the high level (3 kN) of these flights


@dataclass(frozen=True)
class FlightCase:
    """A generated log and its hidden truth."""

    path: Path
    effect: str | None
    parameters: dict
    seed: int
    airspeed_ratios: tuple
    damping: tuple
    noise: tuple
    outcome: str
    wall_time: float


def _plant(effect, rng, noise, duration):
    from aero_dva.flight.hidden_plant import PlantOptions

    params: dict = {}
    fields: dict = {"sensor_noise": noise}
    if effect is None:
        pass
    elif effect == "actuator_lag":
        params["time_constant_s"] = fields["actuator_lag"] = float(rng.uniform(0.5, 1.5))
    elif effect == "sensor_delay":
        params["delay_s"] = fields["sensor_delay"] = int(rng.integers(1, 11)) / 1000.0
    elif effect == "cubic_stiffness":
        share = float(rng.uniform(0.15, 0.40))
        params["kappa_per_rad2"] = fields["cubic_stiffness"] = share / (3 * PITCH_RMS_HIGH**2)
        params["stiffening_at_high_level"] = share
    elif effect == "unsteady_aero":
        params["lag_scale"] = fields["unsteady_aero"] = float(rng.uniform(0.2, 1.2))
    elif effect == "parameter_drift":
        name = "absorber_stiffness"
        change = float(rng.uniform(0.10, 0.25)) * (1 if rng.random() < 0.5 else -1)
        params.update(parameter=name, total_change=change, rate_per_s=change / duration)
        fields.update(drift_parameter=name, drift_rate=change / duration)
    elif effect == "sensor_gain":
        channel = int(rng.integers(2))
        factor = 1.0 + float(rng.uniform(0.05, 0.15)) * (1 if rng.random() < 0.5 else -1)
        gain = [1.0, 1.0, 1.0]
        gain[channel] = factor
        params.update(channel=("plunge", "pitch")[channel], gain=factor)
        fields["sensor_gain"] = tuple(gain)
    else:
        raise ValueError(f"effect must be one of {LIBRARY_EFFECTS + OUTSIDE_EFFECTS} or None, "
                         f"got {effect!r}")
    return PlantOptions(**fields), params


def generate_flight(effect: str | None, seed: int, out_dir, dwell: float = 4.0) -> FlightCase:
    """Fly and record one case into ``out_dir`` (a new rosbag2 directory).

    Parameters
    ----------
    effect : str or None
        One of :data:`LIBRARY_EFFECTS`, :data:`OUTSIDE_EFFECTS`, or None (clean).
    seed : int
        Seeds the case's random choices, the excitation and the sensor noise.
    out_dir : path-like
        Bag directory to create (must not exist).
    dwell : float
        [s] seconds per (airspeed, c2) pair; the flight lasts 12 dwells.
    """
    from aero_dva.bag.runtime_recording import record_runtime
    from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
    from aero_dva.flight.scenario import AirspeedProfile, Scenario

    rng = np.random.default_rng([int(seed), 77])
    three = rng.permutation(np.sort(rng.uniform(0.55, 0.85, 3)))
    ratios = tuple(float(r) for r in np.concatenate([three, three]))  # each visited twice
    damping = (float(rng.uniform(100, 300)), float(rng.uniform(900, 1500)))
    noise = tuple(float(x) * rng.uniform(0.01, 0.04) for x in ACC_RMS)
    duration = len(ratios) * len(damping) * dwell
    plant, params = _plant(effect, rng, noise, duration)
    scenario = Scenario(
        name="flight", duration=duration, block_size=50,
        airspeed=AirspeedProfile("steps", ratios, relative=True), dwell=dwell,
        sweep_damping=damping, force_std=1000.0, seed=int(seed) % (2**31),
        force_levels=(1.0, 3.0), level_dwell=2 * dwell, plant=plant)
    config = dataclasses.replace(load_runtime_config({}), scenario=scenario)
    runtime = FlightRuntime(config)
    rec = record_runtime(out_dir, runtime)
    return FlightCase(Path(out_dir), effect, params, int(seed), ratios, damping, noise,
                      rec.outcome, rec.wall_time)
