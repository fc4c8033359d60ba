"""Load and check the CSV run logs and the rig file of ``spec/diagnosis-interface.md`` (stage 1 of the diagnosis),
and the two types the stages share: :class:`RunLog` (a checked log) and :class:`WindowResiduals` (the gap stage's
per-window residuals that the localisation reads).

Every bad input raises :class:`~furuta_drake.errors.LogError` (a log) or :class:`~furuta_drake.errors.ConfigError`
(the rig file) with one line naming the file, the 1-based line (the header is line 1) and the column, so the
command line can print it and exit 2. Unknown extra columns are not an error: they are listed in
:attr:`RunLog.ignored_columns` and :func:`ignored_columns_note` words the one line the command prints.

Beyond the format, the checks refuse what would otherwise be "diagnosed" as a model error: a time gap (never
interpolated), angles in degrees, angles wrapped into one turn, and (from the data, pooled over the logs) a theta
or phi direction that contradicts the spec's sign conventions.

Sign checks, from Savitzky-Golay second derivatives of the angles. With a = J_arm + m r^2, b = J_p + m l^2,
c = m l r, d = m g l (paper Eq. 1 in the paper's theta direction) the pendulum row reads

    theta_ddot = -(c / b) cos(theta) phi_ddot + (d / b) sin(theta) + sin(theta) cos(theta) phi_dot^2 - friction,

so regressing theta_ddot on cos(theta) phi_ddot and sin(theta) must give a negative coupling coefficient
(beta4 < 0 at the upright) and a positive gravity coefficient; a flipped encoder flips only the coupling. The arm
row, divided by its inertia a + b sin^2(theta), gives phi_ddot = k_u tau / (a + b sin^2 theta) + ..., where
k_u must be positive (phi counts in the direction a positive input accelerates the arm) and near 1 in radians
(about 57 when the angles are in degrees). A sign check decides only when its coefficient is clear (|t| > 10
with the sample count discounted by the smoothing window), the degrees check when k_u is 3 standard errors above
10; otherwise they say nothing. On the real QUBE logs the coupling
comes out at -1.05 (t = 179) against the rig's -c/b = -0.988, and k_u at 0.47 (the voltage logs carry a 1-2
sample lag); their quiet balancing segments alone decide nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.signal import savgol_filter

from furuta_drake.errors import LogError, read_input_text
from furuta_drake.rig import RigParameters
from furuta_drake.yamlio import load_yaml_dataclass

INPUT_COLUMNS = ("torque", "voltage")
ANGLE_COLUMNS = ("theta", "phi")
PERIOD_TOLERANCE = 0.01  # the spec: a constant sample period within 1 %
GAP_FACTOR = 1.5  # a step longer than this many periods is a gap (missing samples)
MAX_THETA_RAD = 4 * math.pi  # beyond two pendulum turns from the upright, the angles are not radians
MIN_SAMPLES = 3
SMOOTHING_WINDOW_S = 0.04  # Savitzky-Golay window for the sign checks [s]
CLEAR_T_STAT = 10.0  # a sign check decides only above this t statistic
DEGREES_GAIN_RATIO = 10.0  # arm response this many times the rig's: the angles are degrees (ratio 57.3)
DEGREES_SIGMAS = 3.0  # ... with the gain that many standard errors above DEGREES_GAIN_RATIO


@dataclass(frozen=True)
class RunLog:
    """One run log, checked and in the paper's sign convention."""

    name: str  # file name (e.g. "balance_1.csv"), used in report windows
    path: str
    time: np.ndarray  # [s], strictly increasing, as logged
    theta: np.ndarray  # [rad], paper convention: theta_logged * rig.theta_direction
    phi: np.ndarray  # [rad]
    input_kind: str  # "torque" | "voltage"
    input: np.ndarray  # as logged: [N m] or [V]
    sample_period: float  # [s], median step
    torque_per_volt: float = 1.0  # kt / R of the rig's motor for voltage logs [N m / V]; 1 for torque logs
    ignored_columns: tuple[str, ...] = ()  # extra columns of the file, not used

    @property
    def torque_command(self) -> np.ndarray:
        """Torque-equivalent of the command [N m]: the torque, or kt V / R for a voltage log (the back-EMF
        term kt ke / R phi_dot is a model term that the surrogate and the replay add)."""
        if self.input_kind == "torque":
            return self.input
        return self.input * self.torque_per_volt


@dataclass
class WindowResiduals:
    """Prediction residuals of one window of a log (the gap stage's output, the localisation's input)."""

    log_name: str
    time: np.ndarray  # [s] sample times of the window (as in the log)
    residual: np.ndarray  # (n, 2) measured - predicted [theta, phi], in encoder counts of the rig file
    state: np.ndarray  # (n, 4) predicted paper-order state [theta, phi, theta_dot, phi_dot]
    torque: np.ndarray  # (n,) torque-equivalent command [N m]
    saturated: np.ndarray  # (n,) bool, |command| >= 0.98 rig torque_limit


def load_rig(path: str | Path) -> RigParameters:
    """The rig file (spec "Rig"), strictly: unknown keys and non-physical values raise ConfigError naming
    file:line:key."""
    return load_yaml_dataclass(path, RigParameters)


def load_log(path: str | Path, rig: RigParameters, rig_path: str | Path = "the rig file") -> RunLog:
    """Read and check one CSV log (spec "Logs"); theta is multiplied by ``rig.theta_direction``.

    ``rig_path`` only names the rig file in the error a voltage log raises when the rig has no motor.
    """
    path = Path(path)
    lines = _read_lines(path)
    header = [name.strip() for name in lines[0].lstrip("\ufeff").split(",")]
    columns = _check_header(path, header)
    input_kind = "torque" if "torque" in columns else "voltage"
    if input_kind == "voltage" and rig.motor is None:
        raise LogError(f"{path}:1: column 'voltage': a voltage log needs a DC motor, but {rig_path} has no "
                       f"'motor' block (add motor: {{resistance, torque_constant, backemf_constant}})")
    data, line_numbers = _parse_numbers(path, lines, header, columns)
    time, theta, phi, command = (np.ascontiguousarray(data[:, i]) for i in range(4))
    where = _Where(path, line_numbers)
    sample_period = _check_time(where, time)
    _check_angles(where, theta, phi)
    theta = theta * rig.theta_direction
    for array in (time, theta, phi, command):
        array.setflags(write=False)
    torque_per_volt = 1.0 if rig.motor is None or input_kind == "torque" else \
        rig.motor.torque_constant / rig.motor.resistance
    known = set(("time",) + ANGLE_COLUMNS + INPUT_COLUMNS)
    return RunLog(name=path.name, path=str(path), time=time, theta=theta, phi=phi, input_kind=input_kind,
                  input=command, sample_period=sample_period, torque_per_volt=torque_per_volt,
                  ignored_columns=tuple(name for name in header if name not in known))


def load_logs(paths, rig: RigParameters, rig_path: str | Path = "the rig file") -> list[RunLog]:
    """:func:`load_log` for each path, then the sign checks pooled over all of them (phi first: a flipped phi
    also flips the arm-pendulum coupling that the theta check reads)."""
    logs = [load_log(path, rig, rig_path) for path in paths]
    check_input_direction(logs, rig, rig_path)
    check_theta_direction(logs, rig, rig_path)
    return logs


def ignored_columns_note(logs: list[RunLog]) -> str | None:
    """The one line saying which extra columns were ignored (spec "Logs"), or None when there were none."""
    per_log = [f"{log.name}: {', '.join(log.ignored_columns)}" for log in logs if log.ignored_columns]
    if not per_log:
        return None
    return "ignored extra columns (" + "; ".join(per_log) + ")"


def check_theta_direction(logs: list[RunLog], rig: RigParameters, rig_path: str | Path = "the rig file") -> None:
    """Raise LogError naming ``theta_direction`` when the arm-pendulum coupling in the data has the wrong sign.

    Fits theta_ddot = k_c cos(theta) phi_ddot + k_g sin(theta) + k_v theta_dot + k_s sin(theta) cos(theta)
    phi_dot^2 on all logs (theta already in the paper's direction). The paper's convention has k_c = -c/b < 0.
    It decides only when k_c is clear and gravity is not clearly reversed (k_g = d/b > 0; in closed-loop
    balancing k_g is confounded with the feedback, so it is not required to be clear). Run
    :func:`check_input_direction` first: a reversed phi also reverses k_c.
    """
    rows = []
    for log in _long_enough(logs):
        theta, _, theta_dot, phi_dot, theta_ddot, phi_ddot = smoothed_derivatives(log)
        rows.append((np.column_stack([np.cos(theta) * phi_ddot, np.sin(theta), theta_dot,
                                      np.sin(theta) * np.cos(theta) * phi_dot**2]), theta_ddot))
    fit = _pooled_fit(rows, logs)
    if fit is None:
        return
    coef, std = fit
    t_stat = coef / std
    if abs(t_stat[0]) <= CLEAR_T_STAT or t_stat[1] < -CLEAR_T_STAT:
        return
    if coef[0] > 0:
        expected = -rig.coupling / rig.pendulum_inertia_total
        names = ", ".join(log.name for log in logs)
        raise LogError(
            f"{rig_path}: theta_direction: {rig.theta_direction} contradicts the logs ({names}): with it the "
            f"arm-pendulum coupling d(theta_ddot)/d(cos(theta) phi_ddot) is {coef[0]:+.3g} (t = {t_stat[0]:.0f}), "
            f"the spec's convention gives {expected:+.3g} (near the upright a positive arm acceleration gives a "
            f"negative pendulum acceleration): the logs count theta the other way, set theta_direction: "
            f"{-rig.theta_direction} (unless it is phi that counts against the input)")


def check_input_direction(logs: list[RunLog], rig: RigParameters, rig_path: str | Path = "the rig file") -> None:
    """Raise LogError when a positive input clearly decelerates the arm (phi counts the wrong way) or the arm
    responds ~57 times more than the rig allows (angles in degrees).

    Fits phi_ddot = k_u tau / (a + b sin^2 theta) + k_c cos(theta) theta_ddot / (a + b sin^2 theta)
    + k_v phi_dot + k_s sign(phi_dot) (+ the centripetal terms), tau the torque-equivalent command.
    """
    a, b = rig.arm_inertia_total, rig.pendulum_inertia_total
    rows = []
    for log in _long_enough(logs):
        theta, _, theta_dot, phi_dot, theta_ddot, phi_ddot = smoothed_derivatives(log)
        inertia = a + b * np.sin(theta) ** 2
        s, c = np.sin(theta), np.cos(theta)
        rows.append((np.column_stack([log.torque_command / inertia, c * theta_ddot / inertia, phi_dot,
                                      np.tanh(phi_dot / 0.05), s * theta_dot**2 / inertia,
                                      s * c * theta_dot * phi_dot / inertia]), phi_ddot))
    fit = _pooled_fit(rows, logs)
    if fit is None:
        return
    coef, std = fit
    names = ", ".join(log.name for log in logs)
    if coef[0] - DEGREES_SIGMAS * std[0] > DEGREES_GAIN_RATIO:
        raise LogError(
            f"{names}: columns 'theta'/'phi': the arm accelerates {coef[0]:.3g} +- {std[0]:.2g} times more per unit "
            f"command than the rig ({rig_path}) allows (57.3 would be degrees): the angles look like degrees; the "
            f"spec wants radians (unless the rig's arm inertia is off by that factor)")
    if coef[0] < -CLEAR_T_STAT * std[0]:
        raise LogError(
            f"{names}: column 'phi' counts against the input: the arm acceleration per unit command is "
            f"{coef[0]:+.3g} times the rig's ({rig_path}) (t = {coef[0] / std[0]:.0f}); the spec wants phi positive in "
            f"the direction a positive input accelerates the arm (negate phi, or the input)")


def smoothed_derivatives(log: RunLog, window_s: float = SMOOTHING_WINDOW_S):
    """theta, phi and their first and second time derivatives from a cubic Savitzky-Golay filter whose window
    spans ``window_s`` (at least 7 samples; the log must be that long): (theta, phi, theta_dot, phi_dot,
    theta_ddot, phi_ddot)."""
    window = _window_samples(log, window_s)
    out = []
    for deriv in (0, 1, 2):
        for signal in (log.theta, log.phi):
            out.append(savgol_filter(signal, window, 3, deriv=deriv, delta=log.sample_period))
    theta, phi, theta_dot, phi_dot, theta_ddot, phi_ddot = out
    return theta, phi, theta_dot, phi_dot, theta_ddot, phi_ddot


def _window_samples(log: RunLog, window_s: float) -> int:
    """Odd Savitzky-Golay window of about ``window_s``, at least 7 samples."""
    return max(7, int(round(window_s / log.sample_period)) | 1)


def _long_enough(logs: list[RunLog]) -> list[RunLog]:
    """The logs long enough for a sign check: at least two smoothing windows."""
    return [log for log in logs if len(log.time) >= 2 * _window_samples(log, SMOOTHING_WINDOW_S)]


def _pooled_fit(rows, logs):
    """Least squares over the stacked rows: (coefficients, standard errors), or None when too short to judge.

    The standard errors count one independent sample per smoothing window (the smoothed residuals are
    correlated over a window)."""
    if not rows:
        return None
    regressors = np.concatenate([r for r, _ in rows])
    target = np.concatenate([t for _, t in rows])
    window = max(_window_samples(log, SMOOTHING_WINDOW_S) for log in _long_enough(logs))
    dof = len(target) / window - regressors.shape[1]
    if dof < 10:
        return None
    scale = np.linalg.norm(regressors, axis=0)
    scale[scale == 0] = 1.0
    coef_scaled, *_ = np.linalg.lstsq(regressors / scale, target, rcond=None)
    coef = coef_scaled / scale
    residual = target - regressors @ coef
    sigma2 = residual @ residual / (len(target) - regressors.shape[1])
    gram_inv = np.linalg.pinv((regressors / scale).T @ (regressors / scale))
    std = np.sqrt(np.maximum(window * sigma2 * np.diag(gram_inv), 1e-300)) / scale
    return coef, std


@dataclass(frozen=True)
class _Where:
    path: Path
    line_numbers: np.ndarray  # 1-based file line of each data row

    def __call__(self, row: int) -> str:
        return f"{self.path}:{int(self.line_numbers[row])}"


def _read_lines(path: Path) -> list[str]:
    lines = read_input_text(path, "a CSV log", LogError).splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    if not lines:
        raise LogError(f"{path}:1: empty file, expected a header line 'time,theta,phi,torque' (or voltage)")
    return lines


def _check_header(path: Path, header: list[str]) -> dict[str, int]:
    seen = {}
    for index, name in enumerate(header):
        if name in seen:
            raise LogError(f"{path}:1: column {index + 1}: duplicate column name {name!r}")
        seen[name] = index
    missing = [name for name in ("time",) + ANGLE_COLUMNS if name not in seen]
    if missing:
        raise LogError(f"{path}:1: missing column {', '.join(repr(m) for m in missing)} (header: "
                       f"{','.join(header)}); required: time, theta, phi and torque or voltage")
    inputs = [name for name in INPUT_COLUMNS if name in seen]
    if not inputs:
        raise LogError(f"{path}:1: no input column: expected 'torque' [N m] or 'voltage' [V] "
                       f"(header: {','.join(header)})")
    if len(inputs) == 2:
        raise LogError(f"{path}:1: both 'torque' and 'voltage' columns: a log has exactly one input column")
    return {name: seen[name] for name in ("time", "theta", "phi", inputs[0])}


def _parse_numbers(path: Path, lines: list[str], header: list[str], columns: dict[str, int]):
    """The four used columns as floats (rows x [time, theta, phi, input]) and each row's file line number."""
    body = lines[1:]
    line_numbers = np.arange(2, len(lines) + 1)
    blank = [i for i, line in enumerate(body) if not line.strip()]
    if blank:
        keep = np.ones(len(body), bool)
        keep[blank] = False
        body = [line for line, k in zip(body, keep) if k]
        line_numbers = line_numbers[keep]
    if not body:
        raise LogError(f"{path}:1: header only, no data rows")
    expected_commas = len(header) - 1
    if sum(line.count(",") for line in body) != expected_commas * len(body):
        for line, number in zip(body, line_numbers):
            if line.count(",") != expected_commas:
                raise LogError(f"{path}:{number}: {line.count(',') + 1} fields, the header has {len(header)}")
    order = list(columns.values())
    try:
        data = np.loadtxt(body, delimiter=",", usecols=order, dtype=float, ndmin=2)
    except ValueError as err:
        _raise_unparsable(path, body, line_numbers, columns)
        raise LogError(f"{path}: cannot read the numbers ({err})") from None
    for j, name in enumerate(columns):
        bad = np.flatnonzero(~np.isfinite(data[:, j]))
        if bad.size:
            row = bad[0]
            raise LogError(f"{path}:{line_numbers[row]}: column '{name}' is {float(data[row, j])}: every value must "
                           f"be a finite number")
    if len(data) < MIN_SAMPLES:
        raise LogError(f"{path}:{line_numbers[-1]}: only {len(data)} data rows, need at least {MIN_SAMPLES}")
    return data, line_numbers


def _raise_unparsable(path: Path, body: list[str], line_numbers: np.ndarray, columns: dict[str, int]) -> None:
    for line, number in zip(body, line_numbers):
        fields = line.split(",")
        for name, index in columns.items():
            try:
                float(fields[index])
            except ValueError:
                raise LogError(f"{path}:{number}: column '{name}': {fields[index].strip()!r} is not a "
                               f"number") from None


def _check_time(where: _Where, time: np.ndarray) -> float:
    step = np.diff(time)
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        row = bad[0] + 1
        kind = "duplicates" if step[bad[0]] == 0 else "goes back from"
        raise LogError(f"{where(row)}: column 'time': {time[row]:.9g} {kind} the previous sample's "
                       f"{time[row - 1]:.9g}: time must be strictly increasing")
    period = float(np.median(step))
    gaps = np.flatnonzero(step > GAP_FACTOR * period)
    if gaps.size:
        row = gaps[0] + 1
        raise LogError(f"{where(row)}: column 'time': gap of {step[gaps[0]]:.6g} s from t = {time[row - 1]:.6g} "
                       f"to t = {time[row]:.6g} s (about {round(step[gaps[0]] / period) - 1} missing samples of "
                       f"{period:.6g} s); the diagnosis does not interpolate: split the log at the gap")
    irregular = np.flatnonzero(np.abs(step - period) > PERIOD_TOLERANCE * period)
    if irregular.size:
        row = irregular[0] + 1
        raise LogError(f"{where(row)}: column 'time': step {step[irregular[0]]:.6g} s deviates by "
                       f"{abs(step[irregular[0]] / period - 1):.1%} from the log's sample period {period:.6g} s "
                       f"(the spec allows 1 %)")
    return period


def _check_angles(where: _Where, theta: np.ndarray, phi: np.ndarray) -> None:
    far = np.flatnonzero(np.abs(theta) > MAX_THETA_RAD)
    if far.size:
        row = far[0]
        raise LogError(f"{where(row)}: column 'theta' is {theta[row]:.6g}, more than two turns from the upright: "
                       f"the angles look like degrees; the spec wants radians (theta 0 upright, unwrapped)")
    for name, angle in (("theta", theta), ("phi", phi)):
        step = np.diff(angle)
        jumps = np.flatnonzero(np.abs(step) > math.pi)
        if not jumps.size:
            continue
        row = jumps[0] + 1
        turns = step[jumps[0]] / (2 * math.pi)
        if abs(turns - round(turns)) < 0.1:
            raise LogError(f"{where(row)}: column '{name}' jumps by {step[jumps[0]]:+.4g} rad in one sample "
                           f"(from {angle[row - 1]:.6g} to {angle[row]:.6g}): the angle is wrapped; the spec wants "
                           f"unwrapped angles (e.g. numpy.unwrap)")
        raise LogError(f"{where(row)}: column '{name}' jumps by {step[jumps[0]]:+.4g} rad in one sample: not a "
                       f"continuous angle in radians (degrees?); the spec wants unwrapped radians")
