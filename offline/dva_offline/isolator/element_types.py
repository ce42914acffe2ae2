"""Type A / B / C classification of Maxwell elements (study section 3.1, Fig. 3.1).

The study defines the types only qualitatively: Type A is damping dominant (small tau_i), Type C
stiffness dominant (large tau_i), Type B neither, and says the boundaries depend on the other
parameters. We make that reproducible with the element's own complex stiffness at the system's
natural frequency w_n:

    K_i(j w_n) = k_i (j w_n tau_i) / (1 + j w_n tau_i),   loss factor eta_i = 1 / (w_n tau_i).

The product ``w_n tau_i`` is the ratio of the element's storage (spring) to loss (damper) part.
The rule is symmetric on a log scale:

* Type A  if w_n tau_i < 1/2   (loss part more than twice the storage part: mostly a damper),
* Type C  if w_n tau_i > 2     (storage part more than twice the loss part: mostly a spring),
* Type B  otherwise            (phase of K_i between 26.6 and 63.4 degrees).

Checked against every label the study prints (see
tests/unit/dva_offline/isolator/test_element_types.py and docs/isolator.md): it agrees
with all labels of Tables 3.3, 3.5-3.7, 4.1, 4.2, 4.5, 4.6, 5.4 and 5.5, and disagrees only with
the three Type B labels of Table 5.6's first elements (w_n tau = 0.26-0.36), which the study
assigns by an indirect argument. No threshold on w_n tau (nor on tau alone) can reproduce all of
the study's labels.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dva_offline.isolator.maxwell_model import MaxwellModel, modal_properties

TYPE_A_BELOW = 0.5  # w_n tau below this: Type A
TYPE_C_ABOVE = 2.0  # w_n tau above this: Type C


@dataclass(frozen=True)
class ElementType:
    """Classification of one Maxwell element.

    Attributes
    ----------
    label : str
        ``"A"``, ``"B"`` or ``"C"``.
    time_constant_s : float
        tau_i = c_i / k_i [s].
    omega_tau : float
        w_n tau_i [-], storage-to-loss ratio of the element at w_n.
    loss_factor : float
        1 / (w_n tau_i) [-].
    phase_deg : float
        Phase of the element's complex stiffness at w_n [deg]: 90 = pure damper, 0 = pure spring.
    """

    label: str
    time_constant_s: float
    omega_tau: float
    loss_factor: float
    phase_deg: float


def classify_omega_tau(omega_tau: float) -> str:
    """Type label for a given w_n tau (see module docstring for the rule)."""
    if not np.isfinite(omega_tau) or omega_tau <= 0:
        raise ValueError(f"omega_tau must be finite and > 0, got {omega_tau}")
    if omega_tau < TYPE_A_BELOW:
        return "A"
    if omega_tau > TYPE_C_ABOVE:
        return "C"
    return "B"


def classify_element(time_constant_s: float, natural_frequency_rad_s: float) -> ElementType:
    """Classify an element of time constant tau [s] in a system of natural frequency [rad/s]."""
    if not time_constant_s > 0:
        raise ValueError(f"time_constant_s must be > 0, got {time_constant_s}")
    if not natural_frequency_rad_s > 0:
        raise ValueError(f"natural_frequency_rad_s must be > 0, got {natural_frequency_rad_s}")
    wt = float(time_constant_s * natural_frequency_rad_s)
    return ElementType(
        label=classify_omega_tau(wt),
        time_constant_s=float(time_constant_s),
        omega_tau=wt,
        loss_factor=1.0 / wt,
        phase_deg=float(np.degrees(np.arctan2(1.0, wt))),
    )


def classify_elements(
    model: MaxwellModel, natural_frequency_rad_s: float | None = None
) -> tuple[ElementType, ...]:
    """Classify every Maxwell element of ``model`` at the model's natural frequency.

    Parameters
    ----------
    model : MaxwellModel
    natural_frequency_rad_s : float, optional
        Frequency to classify at [rad/s]; defaults to the model's own w_n (eq. 4.2).
    """
    if natural_frequency_rad_s is None:
        natural_frequency_rad_s = modal_properties(model).natural_frequency_rad_s
    return tuple(
        classify_element(tau, natural_frequency_rad_s) for tau in model.time_constants
    )
