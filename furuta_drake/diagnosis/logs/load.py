"""Load and check the run logs and the rig file of ``furuta-drake diagnose`` (``docs/diagnose.md``; stage 1 of the
diagnosis), and the two types the stages share: :class:`RunLog` (a checked log) and :class:`WindowResiduals` (the gap
stage's
per-window residuals that the localisation reads).

A log is CSV, Parquet or MCAP (:mod:`~furuta_drake.diagnosis.logs.readers` produces its columns; a
:class:`~furuta_drake.diagnosis.logs.format.LogFormat` maps a lab's column names and angle unit); one code path
here checks them, whatever the format. Every bad input raises :class:`~furuta_drake.errors.LogError` (a log) or
:class:`~furuta_drake.errors.ConfigError` (the rig file) with one line naming the file, the row (for a CSV the
1-based line, the header is line 1) and the column, so the command line can print it and exit 2. Unknown extra
columns are not an error: they are listed in
:attr:`RunLog.ignored_columns` and :func:`ignored_columns_note` words the one line the command prints.

Beyond the format, the checks refuse what would otherwise be "diagnosed" as a model error: a time gap (never
interpolated), angles in degrees, angles wrapped into one turn, and (from the data, pooled over the logs) a theta
or phi direction or a theta zero that contradicts the conventions of ``docs/diagnose.md``. A file of many runs
(``--run-column``) is checked run by run (:func:`load_runs`).

Sign checks, from Savitzky-Golay second derivatives of the angles. With a = J_arm + m r^2, b = J_p + m l^2,
c = m l r, d = m g l (paper Eq. 1 in the paper's theta direction) the pendulum row reads

    theta_ddot = -(c / b) cos(theta) phi_ddot + (d / b) sin(theta) + sin(theta) cos(theta) phi_dot^2 - friction,

so regressing theta_ddot on cos(theta) phi_ddot and sin(theta) must give a negative coupling coefficient
(beta4 < 0 at the upright) and a positive gravity coefficient; a flipped encoder flips only the coupling, a zero
off by pi (``theta_zero``) both. The arm
row, divided by its inertia a + b sin^2(theta), gives phi_ddot = k_u tau / (a + b sin^2 theta) + ..., where
k_u must be positive (phi counts in the direction a positive input accelerates the arm) and near 1 in radians
(about 57 when the angles are in degrees). A sign check decides only when its coefficient is clear (|t| > 10
with the sample count discounted by the smoothing window), the degrees check when k_u is 3 standard errors above
10; otherwise they say nothing (quiet balancing segments alone decide nothing).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.signal import savgol_filter

from furuta_drake.diagnosis.logs.format import LogFormat
from furuta_drake.diagnosis.logs.readers import LOG_TIME, Where, open_log
from furuta_drake.diagnosis.logs.run_column import split_runs
from furuta_drake.errors import LogError
from furuta_drake.rig import THETA_ZEROS, RigParameters

INPUT_COLUMNS = ("torque", "voltage")
ANGLE_COLUMNS = ("theta", "phi")
PERIOD_TOLERANCE = 0.01  # a constant sample period within 1 %
GAP_FACTOR = 1.5  # a step longer than this many periods is a gap (missing samples)
MAX_THETA_RAD = 4 * math.pi  # a file whose theta stays beyond two turns from the upright is not in radians
MIN_SAMPLES = 3
SMOOTHING_WINDOW_S = 0.04  # Savitzky-Golay window for the sign checks [s]
CLEAR_T_STAT = 10.0  # a sign check decides only above this t statistic
DEGREES_GAIN_RATIO = 10.0  # arm response this many times the rig's: the angles are degrees (ratio 57.3)
DECISIVE_MISFIT_RATIO = 4.0  # the best correction of theta must fit the rig's pendulum row this much better
THETA_FIXES = ((-1, 0.0), (1, math.pi), (-1, math.pi))  # (direction, shift) corrections of the logs' theta
DEGREES_SIGMAS = 3.0  # ... with the gain that many standard errors above DEGREES_GAIN_RATIO


@dataclass(frozen=True)
class RunLog:
    """One run log, checked and in the paper's sign convention."""

    name: str  # file name (e.g. "balance_1.csv", "trials.csv[run=7]"), used in report windows
    path: str
    time: np.ndarray  # [s], strictly increasing, as logged
    theta: np.ndarray  # [rad], paper convention: theta_logged * rig.theta_direction
    phi: np.ndarray  # [rad]
    input_kind: str  # "torque" | "voltage"
    input: np.ndarray  # as logged: [N m] or [V]
    sample_period: float  # [s], median step
    torque_per_volt: float = 1.0  # kt / R of the rig's motor for voltage logs [N m / V]; 1 for torque logs
    ignored_columns: tuple[str, ...] = ()  # extra columns of the file, not used
    run: str | None = None  # the run's value in the file's run column (--run-column), None for a file of one run

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


def load_log(
    path: str | Path, rig: RigParameters, rig_path: str | Path = "the rig file", log_format: LogFormat = LogFormat()
) -> RunLog:
    """Read and check one log holding one run (CSV, Parquet or MCAP by its extension; see
    :mod:`~furuta_drake.diagnosis.logs.readers`).

    Parameters
    ----------
    path
        the log file.
    rig
        the rig file's model: ``theta`` is multiplied by its ``theta_direction`` and offset by its ``theta_zero``,
        angles in counts use its ``counts_per_rev``, a voltage log needs its ``motor``.
    rig_path
        names the rig file in errors.
    log_format
        the file's column names, angle unit and MCAP topic (default: the columns under their own names, radians);
        its ``run_column`` must be None (:func:`load_runs` reads a file of many runs).
    """
    if log_format.run_column is not None:
        raise ValueError("load_log reads one run; load_runs splits a file by its run column")
    return load_runs(path, rig, rig_path, log_format)[0]


def load_runs(
    path: str | Path, rig: RigParameters, rig_path: str | Path = "the rig file", log_format: LogFormat = LogFormat()
) -> list[RunLog]:
    """The runs of one log file, each checked on its own time base: the whole file when ``log_format`` has no
    ``run_column``, else one :class:`RunLog` per value of that column (in the order they first appear), named
    ``file.csv[run=7]``. The runs are views of one array per signal, never copies of the table."""
    path = Path(path)
    reader = open_log(path, log_format.topic)
    columns = _resolve_columns(reader, log_format)
    input_kind = next(name for name in INPUT_COLUMNS if name in columns)
    label = {name: log_format.label(name) for name in columns}
    if input_kind == "voltage" and rig.motor is None:
        raise LogError(
            f"{reader.header_where}: column {label['voltage']}: a voltage log needs a DC motor, but "
            f"{rig_path} has no 'motor' block (add motor: {{resistance, torque_constant, "
            f"backemf_constant}})"
        )
    wanted = {column: label[name] for name, column in columns.items()}
    if log_format.run_column is not None:
        if log_format.run_column not in reader.names:
            shown = ", ".join(name for name in reader.names if name != LOG_TIME)
            raise LogError(
                f"{reader.header_where}: no run column {log_format.run_column!r} (--run-column; the file has: {shown})"
            )
        wanted[log_format.run_column] = f"{log_format.run_column!r} (--run-column)"
    data, where = reader.read(wanted)
    for j, column_label in enumerate(wanted.values()):
        bad = np.flatnonzero(~np.isfinite(data[:, j]))
        if bad.size:
            raise LogError(
                f"{where(bad[0])}: column {column_label} is {float(data[bad[0], j])}: every value must be a "
                f"finite number"
            )
    if len(data) < MIN_SAMPLES:
        raise LogError(f"{where(len(data) - 1)}: only {len(data)} data rows, need at least {MIN_SAMPLES}")
    runs: list = [(None, 0, len(data))]
    if log_format.run_column is not None:
        data, runs, where = split_runs(data[:, 4], data, where)
    scale = log_format.radians_per_unit(rig.counts_per_rev)
    time, theta, phi, command = (np.ascontiguousarray(data[:, j]) for j in range(4))
    theta, phi = theta * scale, phi * scale
    _check_theta_range(where, theta, label["theta"], log_format.angle_unit)
    periods = []
    for run, first, last in runs:
        run_where = where if run is None else (lambda row, first=first, run=run: f"{where(first + row)} (run={run})")
        if last - first < MIN_SAMPLES:
            raise LogError(
                f"{run_where(last - first - 1)}: run {run} has only {last - first} samples, need at least {MIN_SAMPLES}"
            )
        periods.append(_check_time(run_where, time[first:last], label["time"]))
        _check_angles(run_where, theta[first:last], phi[first:last], label, log_format.angle_unit)
    theta = theta * rig.theta_direction + rig.theta_zero_angle
    for array in (time, theta, phi, command):
        array.setflags(write=False)
    torque_per_volt = (
        1.0 if rig.motor is None or input_kind == "torque" else rig.motor.torque_constant / rig.motor.resistance
    )
    used = set(wanted) | {LOG_TIME}
    ignored = tuple(name for name in reader.names if name not in used)
    return [
        RunLog(
            name=path.name if run is None else f"{path.name}[run={run}]",
            path=str(path),
            time=time[first:last],
            theta=theta[first:last],
            phi=phi[first:last],
            input_kind=input_kind,
            input=command[first:last],
            sample_period=period,
            torque_per_volt=torque_per_volt,
            ignored_columns=ignored,
            run=run,
        )
        for (run, first, last), period in zip(runs, periods)
    ]


def _resolve_columns(reader, log_format: LogFormat) -> dict[str, str]:
    """furuta-drake's name -> the file's column for time, theta, phi and the one input column; a LogError naming
    the columns the file has, the ones expected and the mapping in force when they do not match."""
    names = set(reader.names)
    column = {name: log_format.column(name) for name in ("time",) + ANGLE_COLUMNS + INPUT_COLUMNS}
    if "time" not in log_format.columns:
        column["time"] = reader.default_time
    shown = [name for name in reader.names if name != LOG_TIME]
    has = f"the file has: {', '.join(shown) or 'no columns'}"
    mapping = f"; mapping in force: {log_format.describe()}" if log_format.describe() else ""
    missing = [name for name in ("time",) + ANGLE_COLUMNS if column[name] not in names]
    if missing:
        expected = ", ".join(log_format.label(name) for name in ("time",) + ANGLE_COLUMNS)
        raise LogError(
            f"{reader.header_where}: missing column {', '.join(log_format.label(m) for m in missing)} "
            f"({has}; expected {expected} and {log_format.label('torque')} or "
            f"{log_format.label('voltage')}{mapping}; --columns maps other names)"
        )
    inputs = [name for name in INPUT_COLUMNS if column[name] in names]
    if not inputs:
        raise LogError(
            f"{reader.header_where}: no input column: expected {log_format.label('torque')} [N m] or "
            f"{log_format.label('voltage')} [V] ({has}{mapping}; --columns maps other names)"
        )
    if len(inputs) == 2:
        raise LogError(
            f"{reader.header_where}: both {log_format.label('torque')} and "
            f"{log_format.label('voltage')} columns: a log has exactly one input column"
        )
    return {name: column[name] for name in ("time",) + ANGLE_COLUMNS + (inputs[0],)}


def load_logs(
    paths, rig: RigParameters, rig_path: str | Path = "the rig file", log_format: LogFormat = LogFormat()
) -> list[RunLog]:
    """:func:`load_runs` for each path (all in ``log_format``), then the sign checks pooled over all of them (phi
    first: a flipped phi also flips the arm-pendulum coupling that the theta check reads)."""
    logs = [log for path in paths for log in load_runs(path, rig, rig_path, log_format)]
    check_input_direction(logs, rig, rig_path)
    check_theta_direction(logs, rig, rig_path)
    return logs


def ignored_columns_note(logs: list[RunLog]) -> str | None:
    """The one line saying which extra columns were ignored, or None when there were none; with why velocity
    columns (:func:`is_velocity_column`) are among them."""
    per_log = [f"{log.name}: {', '.join(log.ignored_columns)}" for log in logs if log.ignored_columns]
    if not per_log:
        return None
    velocities = sorted({name for log in logs for name in log.ignored_columns if is_velocity_column(name)})
    why = (
        f"; the velocity columns ({', '.join(velocities)}) are not used: each window's start state is refined "
        "from the angles themselves, and a logged velocity, even the true one, does not change it"
        if velocities
        else ""
    )
    return "ignored extra columns (" + "; ".join(per_log) + ")" + why


def is_velocity_column(name: str) -> bool:
    """Whether a log's column is named as a velocity (``theta_dot``, ``phi_velocity``, ``alpha_vel``...)."""
    lowered = name.lower()
    return lowered.endswith("_dot") or "vel" in lowered


def check_theta_direction(logs: list[RunLog], rig: RigParameters, rig_path: str | Path = "the rig file") -> None:
    """Raise LogError naming ``theta_direction`` or ``theta_zero`` when the logs contradict the pendulum's sign
    convention or its zero.

    Fits theta_ddot = k_c cos(theta) phi_ddot + k_g sin(theta) + k_v theta_dot + k_s sin(theta) cos(theta)
    phi_dot^2 on all logs (theta already converted). The convention has k_c = -c/b < 0 and k_g = d/b > 0. A
    reversed direction flips k_c only, a zero off by pi flips both (only gravity knows where up is). It decides
    only when k_c is clearly wrong or k_g clearly reversed; the key to name is then the correction (theta -> -theta,
    theta -> theta + pi, or both) under which the rig's own pendulum row (Eq. 1) fits the data best, since in
    closed-loop balancing k_g is confounded with the feedback. Run :func:`check_input_direction` first: a reversed
    phi also reverses k_c.
    """
    signals = [smoothed_derivatives(log) for log in _long_enough(logs)]
    rows = [
        (
            np.column_stack(
                [np.cos(theta) * phi_ddot, np.sin(theta), theta_dot, np.sin(theta) * np.cos(theta) * phi_dot**2]
            ),
            theta_ddot,
        )
        for theta, _, theta_dot, phi_dot, theta_ddot, phi_ddot in signals
    ]
    fit = _pooled_fit(rows, logs)
    if fit is None:
        return
    coef, std = fit
    t_stat = coef / std
    coupling_wrong = t_stat[0] > CLEAR_T_STAT
    if not (coupling_wrong or t_stat[1] < -CLEAR_T_STAT):
        return
    misfits = sorted((_pendulum_row_misfit(signals, rig, *fix), fix) for fix in THETA_FIXES)
    fixes = [fix for _, fix in misfits[: 1 if misfits[1][0] > DECISIVE_MISFIT_RATIO * misfits[0][0] else 2]]
    keys = sorted({key for fix in fixes for key in _fix_keys(fix, rig)}, reverse=True)
    found = (
        f"with {'it' if len(keys) == 1 else 'them'} the arm-pendulum coupling "
        f"d(theta_ddot)/d(cos(theta) phi_ddot) is {coef[0]:+.3g} (t = {t_stat[0]:.0f}) and gravity "
        f"d(theta_ddot)/d(sin(theta)) {coef[1]:+.3g} (t = {t_stat[1]:.0f}); the convention gives "
        f"{-rig.coupling / rig.pendulum_inertia_total:+.3g} and {rig.gravity_torque / rig.pendulum_inertia_total:+.3g}"
    )
    advice = ", or ".join(
        " and ".join(f"{key}: {value}" for key, value in _fix_keys(fix, rig).items()) for fix in fixes
    )
    undecided = (
        " (the logs do not tell which: a log of free swings of the hanging pendulum does)" if len(fixes) > 1 else ""
    )
    raise LogError(
        f"{rig_path}: {(' or ' if undecided else ' and ').join(f'{key}: {getattr(rig, key)}' for key in keys)} "
        f"contradicts the logs ({', '.join(log.name for log in logs)}): {found}: "
        f"set {advice}{undecided}"
    )


def _fix_keys(fix: tuple[int, float], rig: RigParameters) -> dict[str, object]:
    """The rig-file keys and values of a correction (direction, shift) of the logs' theta."""
    direction, shift = fix
    keys: dict[str, object] = {}
    if shift:
        zero = math.remainder(rig.theta_zero_angle + shift, 2 * math.pi)
        keys["theta_zero"] = next(
            (name for name, angle in THETA_ZEROS.items() if math.isclose(abs(zero), angle, abs_tol=1e-9)), f"{zero:.6g}"
        )
    if direction == -1:
        keys["theta_direction"] = -rig.theta_direction
    return keys


def _pendulum_row_misfit(signals, rig: RigParameters, direction: int, shift: float) -> float:
    """Sum of squares of the rig's pendulum row (Eq. 1, no friction) on the smoothed logs with theta replaced by
    direction * theta + shift."""
    b = rig.pendulum_inertia_total
    total = 0.0
    for theta, _, _, phi_dot, theta_ddot, phi_ddot in signals:
        fixed = direction * theta + shift
        predicted = (
            -rig.coupling / b * np.cos(fixed) * phi_ddot
            + rig.gravity_torque / b * np.sin(fixed)
            + np.sin(fixed) * np.cos(fixed) * phi_dot**2
        )
        total += float(np.sum((direction * theta_ddot - predicted) ** 2))
    return total


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
        rows.append(
            (
                np.column_stack(
                    [
                        log.torque_command / inertia,
                        c * theta_ddot / inertia,
                        phi_dot,
                        np.tanh(phi_dot / 0.05),
                        s * theta_dot**2 / inertia,
                        s * c * theta_dot * phi_dot / inertia,
                    ]
                ),
                phi_ddot,
            )
        )
    fit = _pooled_fit(rows, logs)
    if fit is None:
        return
    coef, std = fit
    names = ", ".join(log.name for log in logs)
    if coef[0] - DEGREES_SIGMAS * std[0] > DEGREES_GAIN_RATIO:
        raise LogError(
            f"{names}: columns 'theta'/'phi': the arm accelerates {coef[0]:.3g} +- {std[0]:.2g} times more per unit "
            f"command than the rig ({rig_path}) allows (57.3 would be degrees): the angles look like degrees; the "
            f"diagnosis wants radians: pass --angle-unit deg (unless the rig's arm inertia is off by that factor)"
        )
    if coef[0] < -CLEAR_T_STAT * std[0]:
        raise LogError(
            f"{names}: column 'phi' counts against the input: the arm acceleration per unit command is "
            f"{coef[0]:+.3g} times the rig's ({rig_path}) (t = {coef[0] / std[0]:.0f}); phi must be positive in "
            f"the direction a positive input accelerates the arm (negate phi, or the input)"
        )


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


def _check_time(where: Where, time: np.ndarray, label: str) -> float:
    """The log's sample period [s]; LogError at the first step that is not forward, a gap or irregular."""
    step = np.diff(time)
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        row = bad[0] + 1
        kind = "duplicates" if step[bad[0]] == 0 else "goes back from"
        raise LogError(
            f"{where(row)}: column {label}: {time[row]:.9g} {kind} the previous sample's "
            f"{time[row - 1]:.9g}: time must be strictly increasing"
        )
    period = float(np.median(step))
    gaps = np.flatnonzero(step > GAP_FACTOR * period)
    if gaps.size:
        row = gaps[0] + 1
        raise LogError(
            f"{where(row)}: column {label}: gap of {step[gaps[0]]:.6g} s from t = {time[row - 1]:.6g} "
            f"to t = {time[row]:.6g} s (about {round(step[gaps[0]] / period) - 1} missing samples of "
            f"{period:.6g} s); the diagnosis does not interpolate: split the log at the gap"
        )
    irregular = np.flatnonzero(np.abs(step - period) > PERIOD_TOLERANCE * period)
    if irregular.size:
        row = irregular[0] + 1
        raise LogError(
            f"{where(row)}: column {label}: step {step[irregular[0]]:.6g} s deviates by "
            f"{abs(step[irregular[0]] / period - 1):.1%} from the log's sample period {period:.6g} s "
            f"(at most {PERIOD_TOLERANCE:.0%} is allowed)"
        )
    return period


def _check_theta_range(where: Where, theta: np.ndarray, label: str, unit: str) -> None:
    """LogError when every sample of the file's theta (in radians after the unit conversion) is more than two
    turns from the upright: degrees (a pendulum hanging reads 180). A pendulum that swings through full turns
    in radians gets that far only from nearer, so one sample within two turns clears the file."""
    closest = float(np.min(np.abs(theta)))
    if closest > MAX_THETA_RAD:
        read_as = "" if unit == "rad" else f" (read as {unit}, in radians)"
        hint = "pass --angle-unit deg or give radians" if unit == "rad" else f"check --angle-unit {unit}"
        raise LogError(
            f"{where(0)}: column {label} is {theta[0]:.6g}{read_as} and no sample comes within two turns of the "
            f"upright (the closest is {closest:.6g} away): the angles look like degrees; the diagnosis wants "
            f"radians ({hint}; theta 0 upright, unwrapped)"
        )


def _check_angles(where: Where, theta: np.ndarray, phi: np.ndarray, label: dict[str, str], unit: str) -> None:
    """LogError when the angles (in radians after the unit conversion) jump: wrapped, or not radians."""
    read_as = "" if unit == "rad" else f" (read as {unit}, in radians)"
    hint = "pass --angle-unit deg or give radians" if unit == "rad" else f"check --angle-unit {unit}"
    for name, angle in (("theta", theta), ("phi", phi)):
        step = np.diff(angle)
        jumps = np.flatnonzero(np.abs(step) > math.pi)
        if not jumps.size:
            continue
        row = jumps[0] + 1
        turns = step[jumps[0]] / (2 * math.pi)
        if abs(turns - round(turns)) < 0.1:
            raise LogError(
                f"{where(row)}: column {label[name]} jumps by {step[jumps[0]]:+.4g} rad in one sample "
                f"(from {angle[row - 1]:.6g} to {angle[row]:.6g}){read_as}: the angle is wrapped; the "
                f"diagnosis wants unwrapped angles (e.g. numpy.unwrap)"
            )
        raise LogError(
            f"{where(row)}: column {label[name]} jumps by {step[jumps[0]]:+.4g} rad in one "
            f"sample{read_as}: not a continuous angle in radians (degrees?); the diagnosis wants "
            f"unwrapped radians ({hint})"
        )
