"""The real QUBE-Servo 2 runs as the real-rig studies use them (``data/qube-servo2-real``, loaded and sign-checked by
:func:`furuta_drake.diagnosis.logs.load.load_logs`): which run plays which part, a run seen as a simulation tape, its
balancing and hanging segments, the paper's reference velocity, and the diagnosis that gives the corrected model.

Parts. One swing-up run trains (the diagnosis fits on it, the observers are tuned on its balancing part, the
controller's velocity filter is fitted on it); two swing-ups recorded on other days are held out; the fourth
swing-up, recorded minutes after the train run, balances in a saturated oscillation the others do not show and is
never used to fit anything. The hanging chirp is cut into blocks (:func:`furuta_drake.diagnosis.pipeline.
split_heldout`) over the part where the pendulum stays within ``LINEAR_RANGE`` of hanging: its held-out blocks are
kept from the observers' tuning and from the diagnosis, which fits on the rest of the chirp.

Reference velocity (the paper's Table II): the zero-phase Butterworth filter of the encoder angles'
derivative (:func:`furuta_drake.paper.metrics.butterworth_velocity_reference`) at ``REFERENCE_CUTOFF_HZ``. The paper's
5 Hz suits its 1 kHz rig and slow balancing motion; on the QUBE the balancing loop's limit cycle and the start of
the chirp lie well above 5 Hz, so a 5 Hz reference would erase much of the motion the observers must follow. The
cut-off is set a little over twice the fastest of those motions: the double pass keeps it to within a few percent
while the encoder's quantisation, differentiated at the sample rate, is cut to a small fraction of the velocities
(``reference_properties`` computes both figures for the report).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from furuta_drake.controllers.quanser_swingup import QuanserSwingUpParameters, balancing
from furuta_drake.controllers.swingup import catch_time
from furuta_drake.data import QUBE_REAL_DIR, QUBE_REAL_RIG
from furuta_drake.diagnosis.gap.split import split_heldout
from furuta_drake.diagnosis.logs.load import RunLog, load_logs
from furuta_drake.diagnosis.logs.writers import write_log
from furuta_drake.diagnosis.pipeline import diagnose
from furuta_drake.diagnosis.settings import FAST, DiagnosisSettings
from furuta_drake.linearization import equilibrium_angle
from furuta_drake.paper.metrics import butterworth_velocity_reference
from furuta_drake.rig import RigParameters
from furuta_drake.rig_file import load_rig
from furuta_drake.simulate import SimulationResult

TRAIN_SWINGUP = "swingup_250Hz_10s_a.csv"
HELDOUT_SWINGUPS = ("swingup_250Hz_7s_negdir.csv", "swingup_250Hz_5s_0414.csv")
OSCILLATING_SWINGUP = "swingup_250Hz_10s_satbal.csv"
CHIRP = "chirp_10to0Hz_pos1p5V_250Hz_10s.csv"
SWINGUPS = (TRAIN_SWINGUP, *HELDOUT_SWINGUPS, OSCILLATING_SWINGUP)
LINEAR_RANGE = 0.5  # [rad] the hanging observers run while |theta - pi| stays below this
SETTLE = 1.0  # [s] the balancing figures start this long after the catch
REFERENCE_CUTOFF_HZ = 25.0  # [Hz] the zero-phase Butterworth reference (module docstring)
SMALL_CANDIDATES = ("inertia_mismatch", "input_delay", "actuator_lag")  # the small run's diagnosis


@dataclass
class RealRuns:
    """The real runs, loaded in the package's conventions, with the rig file they were checked against."""

    logs: dict[str, RunLog]
    rig: RigParameters
    rig_path: Path

    def part(self, name: str) -> str:
        """'train', 'heldout' or 'oscillating' (never fitted on) for a swing-up; 'chirp' for the chirp."""
        if name == TRAIN_SWINGUP:
            return "train"
        if name in HELDOUT_SWINGUPS:
            return "heldout"
        return "oscillating" if name == OSCILLATING_SWINGUP else "chirp"


def load_real_runs(names=SWINGUPS + (CHIRP,), rig_path: Path = QUBE_REAL_RIG) -> RealRuns:
    """The runs ``names`` of ``data/qube-servo2-real`` checked against ``rig_path`` (theta_direction applied)."""
    rig = load_rig(rig_path)
    logs = load_logs([QUBE_REAL_DIR / name for name in names], rig, rig_path)
    return RealRuns({log.name: log for log in logs}, rig, Path(rig_path))


def log_result(
    log: RunLog, params: QuanserSwingUpParameters | None = None, theta_offset: float = 0.0, samples: slice = slice(None)
) -> SimulationResult:
    """A real run seen as a simulation tape: ``measured`` the encoder angles (theta minus ``theta_offset``),
    ``torque`` the torque-equivalent command kt V / R, ``state`` unknown (NaN), the ``swingup_mode`` the
    controller's balance predicate gives on the angles (:func:`~furuta_drake.controllers.quanser_swingup.balancing`,
    default parameters), ``time`` from 0 at the first of ``samples``."""
    params = params or QuanserSwingUpParameters()
    theta, phi = log.theta[samples], log.phi[samples]
    time = log.time[samples] - log.time[samples][0]
    mode = balancing(params, theta).astype(float)[:, None]
    return SimulationResult(
        time=time,
        state=np.full((time.size, 4), np.nan),
        measured=np.column_stack([theta - theta_offset, phi]),
        torque=log.torque_command[samples],
        true_friction=np.full((time.size, 2), np.nan),
        signals={"swingup_mode": mode},
    )


def voltage_of(result: SimulationResult, rig: RigParameters) -> np.ndarray:
    """The voltage [V] behind a tape's torque-equivalent command (kt V / R of ``rig.motor``)."""
    return result.torque * rig.motor.resistance / rig.motor.torque_constant


def catch_index(result: SimulationResult) -> int | None:
    """The sample of the last hand-over to balancing (:func:`~furuta_drake.controllers.swingup.catch_time`), None
    when the run ends swinging."""
    t = catch_time(result)
    return None if not math.isfinite(t) else int(np.searchsorted(result.time, t - 1e-9))


def balancing_samples(result: SimulationResult) -> slice | None:
    """The balancing window: from ``SETTLE`` after the catch to the end (None when it never caught or the window
    is empty)."""
    k = catch_index(result)
    if k is None:
        return None
    start = int(np.searchsorted(result.time, result.time[k] + SETTLE - 1e-9))
    return slice(start, None) if start < result.time.size - 1 else None


def hanging_samples(log: RunLog) -> slice:
    """From the start of ``log`` to the first sample where |theta - theta_eq| leaves ``LINEAR_RANGE`` (theta_eq
    the hanging angle of its first sample's turn)."""
    offset = np.abs(log.theta - equilibrium_angle(log.theta[0], "hanging"))
    outside = np.flatnonzero(offset >= LINEAR_RANGE)
    return slice(0, int(outside[0]) if outside.size else log.time.size)


def chirp_blocks(log: RunLog) -> tuple[np.ndarray, np.ndarray]:
    """(train, held-out) sample masks of ``log``: its hanging segment cut into blocks by
    :func:`~furuta_drake.diagnosis.gap.split.split_heldout`; the rest of the log (large swings) is in neither."""
    segment = hanging_samples(log)
    part = dataclasses.replace(
        log, time=log.time[segment], theta=log.theta[segment], phi=log.phi[segment], input=log.input[segment]
    )
    train, heldout, _ = split_heldout([part])
    masks = []
    for blocks in (train, heldout):
        mask = np.zeros(log.time.size, bool)
        for block in blocks:
            mask |= np.isin(log.time, block.time)
        masks.append(mask)
    return masks[0], masks[1]


def reference_velocity(log: RunLog, cutoff_hz: float = REFERENCE_CUTOFF_HZ) -> np.ndarray:
    """The paper's reference: zero-phase Butterworth velocities [theta_dot, phi_dot] [rad/s] of the whole log."""
    return butterworth_velocity_reference(np.column_stack([log.theta, log.phi]), log.sample_period, cutoff_hz)


def reference_properties(
    rig: RigParameters, period: float, motion_hz: float, cutoff_hz: float = REFERENCE_CUTOFF_HZ
) -> dict[str, float]:
    """What the reference keeps and what it lets through, computed on synthetic signals: the gain on a sinusoid
    of ``motion_hz`` (amplitude of the reference over the true velocity's) and the RMS [rad/s] of the velocity a
    quantised ramp (constant true velocity) leaves, at ``rig.counts_per_rev`` and ``period``."""
    time = np.arange(0.0, 20.0, period)
    omega = 2.0 * math.pi * motion_hz
    true = np.cos(omega * time)
    reference = butterworth_velocity_reference((np.sin(omega * time) / omega)[:, None], period, cutoff_hz)[:, 0]
    inner = slice(time.size // 4, -time.size // 4)
    gain = float(np.dot(reference[inner], true[inner]) / np.dot(true[inner], true[inner]))
    count = rig.encoder_resolution
    ramp = count * np.round((0.37 * time) / count)  # 0.37 rad/s: not a multiple of one count per sample
    noise = butterworth_velocity_reference(ramp[:, None], period, cutoff_hz)[inner, 0] - 0.37
    return {
        "cutoff_hz": cutoff_hz,
        "motion_hz": motion_hz,
        "gain_at_motion": gain,
        "quantisation_rms": float(np.sqrt(np.mean(noise**2))),
    }


def write_segment(path: Path, log: RunLog, samples: slice, rig: RigParameters) -> Path:
    """``samples`` of ``log`` as a log file in the rig's own convention (theta times ``theta_direction`` again, so
    that the diagnosis reads it as it reads the original), time from 0."""
    time = log.time[samples]
    return write_log(
        path,
        {
            "time": time - time[0],
            "voltage": log.input[samples],
            "theta": log.theta[samples] * rig.theta_direction,
            "phi": log.phi[samples],
        },
    )


def runs_of(mask: np.ndarray) -> list[slice]:
    """The contiguous runs of True in ``mask`` as slices."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return [slice(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]


def diagnose_corrected_model(runs: RealRuns, folder: Path, small: bool = False, progress=None):
    """The diagnosis behind the corrected model: fitted on the train swing-up and the chirp without its held-out
    blocks (written as logs into ``folder``), judged on the held-out swing-ups. Returns (Diagnosis, train paths,
    held-out paths). ``small``: three candidates and quick settings."""
    folder.mkdir(parents=True, exist_ok=True)
    chirp = runs.logs[CHIRP]
    _, held = chirp_blocks(chirp)
    train = [QUBE_REAL_DIR / TRAIN_SWINGUP]
    for k, samples in enumerate(runs_of(~held)):
        train.append(write_segment(folder / f"chirp_train_{k}.csv", chirp, samples, runs.rig))
    heldout = [QUBE_REAL_DIR / name for name in HELDOUT_SWINGUPS]
    return run_diagnosis(runs.rig_path, train, heldout, small, progress), train, heldout


def run_diagnosis(rig_path: Path, train: list, heldout: list, small: bool, progress=None):
    """:func:`~furuta_drake.diagnosis.pipeline.diagnose` with the studies' settings: every candidate and the
    command's settings, or (``small``) ``SMALL_CANDIDATES`` with quick settings and no Drake replay."""
    settings = dataclasses.replace(FAST, replay=False, max_effects=2) if small else DiagnosisSettings()
    return diagnose(
        rig=rig_path,
        train=train,
        heldout=heldout,
        settings=settings,
        candidates=list(SMALL_CANDIDATES) if small else None,
        progress=progress,
    )


__all__ = [
    "TRAIN_SWINGUP",
    "HELDOUT_SWINGUPS",
    "OSCILLATING_SWINGUP",
    "CHIRP",
    "SWINGUPS",
    "LINEAR_RANGE",
    "SETTLE",
    "REFERENCE_CUTOFF_HZ",
    "RealRuns",
    "load_real_runs",
    "log_result",
    "voltage_of",
    "catch_index",
    "balancing_samples",
    "hanging_samples",
    "chirp_blocks",
    "reference_velocity",
    "reference_properties",
    "write_segment",
    "runs_of",
    "diagnose_corrected_model",
    "run_diagnosis",
]
