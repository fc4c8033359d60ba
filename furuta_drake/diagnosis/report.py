"""The diagnosis' output directory: ``report.json``, ``report.md``, ``report.html``, PNG plots, ``config.yaml``
(exact inputs with their sha256, versions, seeds, options), ``fitted_model.yaml`` (the fitted simulate config, so
``furuta-drake simulate --config fitted_model.yaml`` runs the corrected model) and ``fitted_rig.yaml`` (the rig
file with the accepted effects, to continue from); ``docs/diagnose.md`` describes each.

``report.json`` has the contract's keys in its order (later keys after them), every number a plain float
rounded to :data:`SIGNIFICANT_DIGITS` significant digits (non-finite as null), so the same inputs give
byte-identical files. The directory is written through :func:`furuta_drake.outputs.atomic_output_dir`: it
appears complete or not at all.

Effect curves (:func:`effect_curve`) read each effect's fitted parameters in SI units as the ranking lists them,
as the effect's own levels (not increments over the rig file): friction torque against velocity for the friction
effects, the command-to-torque map for dead zone, saturation and gain (a dead zone shifts the command towards
zero by its width, as Simulink's Dead Zone block), the spring torque -k (phi - phi_0) against phi, the unit step
response for lag and delay, and a bar chart of the parameters for the rest.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from furuta_drake.diagnosis.localize import band_power
from furuta_drake.diagnosis.logs import WindowResiduals
from furuta_drake.diagnosis.surrogate import Model, applied_torque, spring_torque
from furuta_drake.diagnosis.torque_report import plot_torque, torque_markdown, torque_sentence
from furuta_drake.outputs import atomic_output_dir, versions
from furuta_drake.rig import RigParameters
from furuta_drake.yamlio import dump_yaml_dataclass, to_plain

SIGNIFICANT_DIGITS = 6
SPEC_KEYS = ("verdict", "effects", "gap", "ranking", "localization")
_NUMBER = (int, float)
FRICTION_EFFECTS = (
    "arm_coulomb_friction",
    "arm_viscous_friction",
    "arm_stribeck",
    "friction_asymmetry",
    "pendulum_friction",
)
MAX_PLOT_POINTS = 20000  # per line of the residual plot; longer series are strided


@dataclass
class EffectCurve:
    """One fitted-effect plot: named curves y(x), or bars when ``bars`` is true (x are then labels)."""

    effect: str
    title: str
    x_label: str
    y_label: str
    x: np.ndarray | list[str]
    curves: dict[str, np.ndarray] = field(default_factory=dict)
    bars: bool = False


def check_report(report: dict) -> None:
    """Raise ValueError unless ``report`` has every key of the spec's report.json with the spec's types."""
    _require(report, "", {"verdict": str, "effects": list, "gap": dict, "ranking": list, "localization": dict})
    if not all(isinstance(e, str) for e in report["effects"]):
        raise ValueError("report.effects must be a list of effect names")
    gap = report["gap"]
    _require(gap, "gap", {"metric": str, "nominal": dict, "with_effects": dict, "heldout_reduction": _NUMBER})
    for name in ("nominal", "with_effects"):
        _require(gap[name], f"gap.{name}", {"train": _NUMBER, "heldout": _NUMBER})
    for i, entry in enumerate(report["ranking"]):
        _require(
            entry,
            f"ranking[{i}]",
            {"effect": str, "params": dict, "heldout_gap": _NUMBER, "heldout_reduction": _NUMBER, "evidence": _NUMBER},
        )
        for key, value in entry["params"].items():
            if not _is_number(value) and not (key.split(".")[-1] == "form" and isinstance(value, str)):
                raise ValueError(f"report.ranking[{i}].params.{key} must be a number (or a form's name), got {value!r}")
    loc = report["localization"]
    _require(loc, "localization", {"signals": dict, "windows": list, "regimes": list, "frequency_bands": list})
    _require(loc["signals"], "localization.signals", {"theta": _NUMBER, "phi": _NUMBER})
    for i, w in enumerate(loc["windows"]):
        _require(w, f"localization.windows[{i}]", {"log": str, "start": _NUMBER, "end": _NUMBER, "why": str})
    for i, r in enumerate(loc["regimes"]):
        _require(r, f"localization.regimes[{i}]", {"regime": str, "share_of_gap": _NUMBER})
    for i, b in enumerate(loc["frequency_bands"]):
        _require(
            b, f"localization.frequency_bands[{i}]", {"low_hz": _NUMBER, "high_hz": _NUMBER, "share_of_gap": _NUMBER}
        )


def report_json(report: dict) -> str:
    """The deterministic text of report.json: spec keys first in the spec's order, floats rounded."""
    check_report(report)
    ordered = {key: report[key] for key in SPEC_KEYS}
    ordered.update((key, value) for key, value in report.items() if key not in SPEC_KEYS)
    return json.dumps(_canonical(ordered), indent=2, allow_nan=False) + "\n"


def input_record(
    *,
    rig_path: str | Path,
    train: Sequence[str | Path],
    heldout: Sequence[str | Path] = (),
    seeds: dict | None = None,
    options: dict | None = None,
) -> dict:
    """What config.yaml records: each input file with its sha256, the versions, the seeds and the options."""

    def entry(path):
        path = Path(path)
        return {"path": str(path), "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}

    return {
        "rig": entry(rig_path),
        "train": [entry(p) for p in train],
        "heldout": [entry(p) for p in heldout],
        "versions": versions(),
        "seeds": dict(seeds or {}),
        "options": dict(options or {}),
    }


def write_report(out_dir: str | Path, diagnosis, *, force: bool = False, protect: Sequence[str | Path] = ()) -> Path:
    """Write the whole output directory of ``diagnosis`` (a :class:`~furuta_drake.diagnosis.result.Diagnosis`
    with its artifacts) atomically (see :func:`write_report_files`); return its path. ``protect`` lists paths
    (the input logs and rig) that ``force`` must never delete."""
    with atomic_output_dir(out_dir, force=force, protect=protect) as staging:
        write_report_files(staging, diagnosis)
    return Path(out_dir)


def write_report_files(directory: Path, diagnosis) -> list[str]:
    """Write report.json, the plots, report.md, report.html, config.yaml, fitted_model.yaml and fitted_rig.yaml
    into an existing directory; return the written file names."""
    from furuta_drake.diagnosis.html import report_html

    directory = Path(directory)
    artifacts = diagnosis.artifacts
    text = report_json(diagnosis.to_json())
    report = json.loads(text)
    (directory / "report.json").write_text(text)
    figures = {
        "residuals.png": "Prediction residuals over time (worst windows shaded)",
        "residual_spectra.png": "Residual power spectral density, before and after the effects",
    }
    plot_residuals(artifacts.before, artifacts.after, report["localization"]["windows"], directory / "residuals.png")
    plot_spectra(artifacts.before, artifacts.after, artifacts.noise_variance, directory / "residual_spectra.png")
    for curve in artifacts.curves:
        name = f"effect_{curve.effect}.png"
        plot_effect_curve(curve, directory / name)
        figures[name] = curve.title
    for joint, entry in report.get("unmodelled_torque", {}).items():
        plot_torque(joint, entry, artifacts.torque_scatter[joint], directory / entry["plot"])
        figures[entry["plot"]] = torque_sentence(joint, entry).rstrip(".")
    (directory / "config.yaml").write_text(
        yaml.safe_dump(to_plain(artifacts.record), sort_keys=False, default_flow_style=False)
    )
    (directory / "fitted_model.yaml").write_text(dump_yaml_dataclass(artifacts.fitted_config))
    (directory / "fitted_rig.yaml").write_text(dump_yaml_dataclass(artifacts.fitted_rig))
    (directory / "report.md").write_text(report_markdown(report, figures))
    (directory / "report.html").write_text(report_html(report, directory, figures))
    return ["report.json", *figures, "config.yaml", "fitted_model.yaml", "fitted_rig.yaml", "report.md", "report.html"]


def _with_interval(key: str, value, intervals: dict) -> str:
    """``key = value [low, high] unit`` (the interval and unit where known)."""
    from furuta_drake.diagnosis.candidates import UNITS

    unit = UNITS.get(key.split(".")[-1], "")
    if isinstance(value, str):
        return f"{key} = {value}"
    text = f"{key} = {_fmt(value)}"
    if key in intervals:
        low, high = intervals[key]
        text += f" [{_fmt(low)}, {_fmt(high)}]"
    return text + (f" {unit}" if unit and unit != "-" else "")


def report_markdown(report: dict, figures: dict[str, str]) -> str:
    """report.md: the same content as report.json for a person, with the figures linked relatively."""
    gap = report["gap"]
    effects = ", ".join(f"`{e}`" for e in report["effects"]) or "none"
    lines = ["# Sim-to-real gap diagnosis", "", f"**Verdict: `{report['verdict']}`**. Accepted effects: {effects}.", ""]
    if report.get("choice"):
        lines += [report["choice"], ""]
    for pair in report.get("confusable", []):
        lines += [f"**Confusable:** `{pair['effects'][0]}` and `{pair['effects'][1]}`: {pair['why']}.", ""]
    lines += [
        "## Gap",
        "",
        f"Metric: {gap['metric']}",
        "",
        "| model | train | held-out |",
        "|---|---:|---:|",
        f"| nominal (rig file) | {_fmt(gap['nominal']['train'])} | {_fmt(gap['nominal']['heldout'])} |",
        f"| with the accepted effects | {_fmt(gap['with_effects']['train'])} | "
        f"{_fmt(gap['with_effects']['heldout'])} |",
        "",
        f"Held-out reduction: {_percent(gap['heldout_reduction'])} (1 - gap with effects / nominal gap, on "
        f"held-out logs; {gap.get('evaluated_by', '')}).",
        "",
    ]
    if report.get("steps"):
        lines += [
            "## Steps",
            "",
            "| step | effect accepted | held-out gap [counts] | reduction over nominal | "
            "over the previous step | over the model of all the others [lower bound] |",
            "|---:|---|---:|---:|---:|---:|",
        ]
        lines += [
            f"| {i} | `{step['effect']}` | {_fmt(step['heldout_gap'])} | {_percent(step['heldout_reduction'])} "
            f"| {_percent(step['reduction_over_previous'])} | {_percent(step.get('reduction_over_others'))} "
            f"[{_percent(step.get('evidence_over_others'))}] |"
            for i, step in enumerate(report["steps"], 1)
        ]
        lines.append("")
    lines += [f"How effects are accepted: {report.get('rule', '')}", ""]
    if report.get("holdout"):
        lines += [f"Held-out data: {report['holdout']}", ""]
    if report.get("uncertainty"):
        lines += [f"Parameter intervals: {report['uncertainty']}.", ""]
    lines += [
        "## Ranking of the candidates",
        "",
        "| # | step | effect | fitted parameters: value [95 % interval] unit | held-out gap | "
        "held-out reduction | evidence |",
        "|---:|---:|---|---|---:|---:|---:|",
    ]
    ranked = [entry for entry in report["ranking"] if entry.get("status", "ok") == "ok"]
    for i, entry in enumerate(ranked, 1):
        params = ", ".join(_with_interval(k, v, entry.get("params_ci", {})) for k, v in entry["params"].items())
        lines.append(
            f"| {i} | {entry.get('step', 1)} | `{entry['effect']}` | {params} | "
            f"{_fmt(entry['heldout_gap'])} | {_percent(entry['heldout_reduction'])} | "
            f"{_fmt(entry['evidence'])} |"
        )
    failed = [entry for entry in report["ranking"] if entry.get("status", "ok") != "ok"]
    if failed:
        lines += ["", "Failed candidates (left out of the decision):", ""]
        lines += [f"- `{entry['effect']}` (step {entry.get('step', 1)}): {entry.get('reason', '')}" for entry in failed]
    accepted = next(
        (
            entry
            for entry in ranked
            if entry["effect"].split("+") == [step["effect"] for step in report.get("steps", [])]
        ),
        None,
    )
    if accepted is not None and accepted.get("at_bounds"):
        lines += [
            "",
            f"The accepted fit ended at the edge of its search range: {', '.join(accepted['at_bounds'])}. "
            "The effect's law is stretched to its limit there; it may stand in for an unmodelled effect of "
            "a similar shape.",
        ]
    if report.get("detection_limits"):
        lines += [
            "",
            "## Detection limits",
            "",
            (
                "No effect larger than these would have gone unseen in these logs"
                if report["verdict"] == "none"
                else "Effects not accepted would have been detected at these sizes"
            )
            + " (injected into the "
            "model's own prediction of the held-out windows, judged by the same rule):",
            "",
            "| effect | parameter | smallest detected | note |",
            "|---|---|---:|---|",
        ]
        lines += [
            f"| `{limit['effect']}` | {limit['param']} | "
            f"{_fmt(limit['value'])}{' ' + limit['unit'] if limit['value'] is not None else ''} | "
            f"{_cell(limit.get('note', ''))} |"
            for limit in report["detection_limits"]
        ]
    if report.get("consistency"):
        consistency = report["consistency"]
        lines += [
            "",
            "## Consistency across splits of the logs",
            "",
            consistency["judgement"] + ".",
            "",
            "| fold | verdict | effects |",
            "|---:|---|---|",
        ]
        lines += [
            f"| {i} | `{verdict}` | {', '.join(found) or '-'} |"
            for i, (verdict, found) in enumerate(
                zip(consistency["verdicts"], consistency.get("effects") or [[]] * consistency["folds"]), 1
            )
        ]
    lines += torque_markdown(report)
    lines += _localization_markdown(report["localization"])
    lines += ["", "## Figures", ""]
    for name, caption in figures.items():
        lines += [f"![{caption}]({name})", "", f"*{caption}.*", ""]
    lines += [
        "## Files",
        "",
        "- `report.json`: this report for programs; `report.html`: this report in one file.",
        "- `config.yaml`: the exact inputs (paths and sha256), versions, seeds and options.",
        "- `fitted_model.yaml`: the fitted model as a simulate config "
        "(`furuta-drake simulate --config fitted_model.yaml`).",
        "- `fitted_rig.yaml`: the rig file with the accepted effects in its `effects:` section (a further "
        "diagnosis continues from it: `furuta-drake diagnose --rig fitted_rig.yaml ...`).",
    ]
    return "\n".join(lines) + "\n"


def _localization_markdown(loc: dict) -> list[str]:
    after = loc.get("after")
    lines = ["", "## Where the gap is", ""]
    if "basis" in loc:
        lines += [f"Shares of the {loc['basis']}.", ""]
    header = "| signal | share (nominal) |" + (" share (with effects) |" if after else "")
    lines += [header, "|---|---:|" + ("---:|" if after else "")]
    for signal in ("theta", "phi"):
        row = f"| {signal} | {_percent(loc['signals'][signal])} |"
        lines.append(row + (f" {_percent(after['signals'][signal])} |" if after else ""))
    for title, block in (
        ("Worst time windows (nominal model):", loc),
        ("Worst time windows with the effects:", after or {}),
    ):
        if block.get("windows"):
            lines += ["", title, "", "| log | start [s] | end [s] | share of gap | why |", "|---|---:|---:|---:|---|"]
            lines += [
                f"| {_cell(w['log'])} | {_fmt(w['start'])} | {_fmt(w['end'])} | "
                f"{_percent(w.get('share_of_gap'))} | {_cell(w['why'])} |"
                for w in block["windows"]
            ]
    lines += [
        "",
        "| regime | definition | share of samples | share of gap (nominal) |"
        + (" share of gap (with effects) |" if after else ""),
        "|---|---|---:|---:|" + ("---:|" if after else ""),
    ]
    after_regimes = {r["regime"]: r for r in after["regimes"]} if after else {}
    for r in loc["regimes"]:
        row = (
            f"| {r['regime']} | {_cell(r.get('definition', ''))} | {_percent(r.get('share_of_samples'))} | "
            f"{_percent(r['share_of_gap'])} |"
        )
        if after:
            row += f" {_percent(after_regimes.get(r['regime'], {}).get('share_of_gap'))} |"
        lines.append(row)
    lines += [
        "",
        "| band [Hz] | share of gap (nominal) |" + (" share of gap (with effects) |" if after else ""),
        "|---|---:|" + ("---:|" if after else ""),
    ]
    after_bands = {(b["low_hz"], b["high_hz"]): b for b in after["frequency_bands"]} if after else {}
    for b in loc["frequency_bands"]:
        row = f"| {_fmt(b['low_hz'])}-{_fmt(b['high_hz'])} | {_percent(b['share_of_gap'])} |"
        if after:
            row += f" {_percent(after_bands.get((b['low_hz'], b['high_hz']), {}).get('share_of_gap'))} |"
        lines.append(row)
    return lines


def plot_residuals(
    before: list[WindowResiduals], after: list[WindowResiduals] | None, worst: list[dict], path: Path
) -> None:
    """One row per log: theta and phi residuals [counts] against time, worst windows shaded; the residuals
    with the effects dashed."""
    logs = sorted({w.log_name for w in before})
    fig = Figure(figsize=(10, 2.4 * len(logs) + 0.6))
    axes = fig.subplots(len(logs), 1, squeeze=False)[:, 0]
    for ax, log in zip(axes, logs):
        for windows, style, label in ((before, "-", "nominal"), (after or [], "--", "with effects")):
            time, residual = _joined([w for w in windows if w.log_name == log])
            if time.size == 0:
                continue
            for column, (signal, color) in enumerate((("theta", "tab:blue"), ("phi", "tab:orange"))):
                ax.plot(
                    time,
                    residual[:, column],
                    style,
                    color=color,
                    lw=0.7 if style == "-" else 0.9,
                    label=f"{signal}, {label}",
                )
        for w in worst:
            if w["log"] == log:
                ax.axvspan(w["start"], w["end"], color="tab:red", alpha=0.15, lw=0)
        ax.set_title(log, fontsize=9)
        ax.set_ylabel("residual [counts]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, ncol=4, loc="upper right")
    axes[-1].set_xlabel("time [s]")
    _save(fig, path)


def plot_spectra(
    before: list[WindowResiduals], after: list[WindowResiduals] | None, noise_variance: float, path: Path
) -> None:
    """Residual power spectral density [counts^2/Hz] per signal, averaged over the windows, before and after,
    with the white sensor-noise level 2 s^2 dt."""
    fig = Figure(figsize=(10, 4))
    axes = fig.subplots(1, 2)
    dt = float(np.median(np.concatenate([np.diff(w.time) for w in before])))
    for windows, style, label in ((before, "-", "nominal"), (after or [], "--", "with effects")):
        if not windows:
            continue
        centers, density = residual_psd(windows)
        for column, ax in enumerate(axes):
            ax.loglog(centers, np.maximum(density[:, column], 1e-12), style, label=label)
    for ax, signal in zip(axes, ("theta", "phi")):
        ax.axhline(2 * noise_variance * dt, color="0.5", lw=0.8, ls=":", label="encoder noise level")
        ax.set_title(f"{signal} residual", fontsize=9)
        ax.set_xlabel("frequency [Hz]")
        ax.grid(alpha=0.3, which="both")
    axes[0].set_ylabel("PSD [counts$^2$/Hz]")
    axes[0].legend(fontsize=8)
    _save(fig, path)


def residual_psd(windows: list[WindowResiduals], bins: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """(bin centres [Hz], one-sided PSD [counts^2/Hz] per signal (bins x 2)) over log-spaced bins from the
    longest window's resolution to the Nyquist frequency: per bin, the windows' periodogram power summed,
    divided by their sample count and the bin width (white noise of variance s^2 gives 2 s^2 dt). Windows of a
    coarser sample rate count only in the bins below their Nyquist frequency."""
    rates = [1.0 / float(np.median(np.diff(w.time))) for w in windows]
    longest = max(len(w.time) / rate for w, rate in zip(windows, rates))
    edges = np.concatenate([[0.0], np.geomspace(1.0 / longest, 0.5 * max(rates), bins)])
    power, samples = np.zeros((bins, 2)), np.zeros(bins)
    for w in windows:
        window_edges, band = band_power(w, 0.0, edges[:-1])
        power[: len(window_edges) - 1] += band
        samples[: len(window_edges) - 1] += len(w.time)
    centers = np.sqrt(np.maximum(edges[:-1], edges[1] / 2) * edges[1:])
    return centers, power / np.maximum(samples, 1)[:, None] / np.diff(edges)[:, None]


def effect_curve(effect: str, params: dict[str, float], rig: RigParameters) -> EffectCurve:
    """The plot of a fitted effect against the rig file's nominal model (see the module docstring)."""
    if effect in FRICTION_EFFECTS:
        return _friction_curve(effect, params, rig)
    limit = rig.torque_limit
    command = np.linspace(-1.2 * limit, 1.2 * limit, 481)
    model = Model.from_rig(rig)
    if effect in ("actuator_deadzone", "actuator_saturation", "torque_gain_error"):
        fitted = {
            "actuator_deadzone": lambda: model.replace(
                deadzone=params["deadzone"], deadzone_form=params.get("form", "subtract")
            ),
            "actuator_saturation": lambda: model.replace(
                saturation=params["limit"], saturation_form=params.get("form", "hard")
            ),
            "torque_gain_error": lambda: model.replace(gain=params["gain"]),
        }[effect]()
        return EffectCurve(
            effect,
            f"Fitted {effect}: command to applied torque",
            "command [N m]",
            "applied torque [N m]",
            command,
            {"nominal": command, "fitted": applied_torque(fitted, command)},
        )
    if effect == "arm_spring":
        spring = model.replace(
            spring_stiffness=params["stiffness"],
            spring_cubic=params.get("cubic_stiffness", 0.0),
            spring_equilibrium=params.get("equilibrium", 0.0),
        )
        phi = np.linspace(-math.pi / 2, math.pi / 2, 361) + spring.spring_equilibrium
        return EffectCurve(
            effect,
            "Fitted arm_spring: restoring torque",
            "phi [rad]",
            "spring torque [N m]",
            phi,
            {"nominal": 0.0 * phi, "fitted": spring_torque(spring, phi)},
        )
    if effect in ("actuator_lag", "input_delay"):
        scale = params["time_constant"] if effect == "actuator_lag" else params["delay"]
        time = np.linspace(0.0, max(5 * scale, 10 * rig.sample_period), 501)
        step = (time >= 0).astype(float)
        fitted = 1.0 - np.exp(-time / scale) if effect == "actuator_lag" else (time >= scale).astype(float)
        return EffectCurve(
            effect,
            f"Fitted {effect}: response to a unit step of the command",
            "time [s]",
            "applied / commanded torque",
            time,
            {"nominal": step, "fitted": fitted},
        )
    names = list(params)
    return EffectCurve(
        effect,
        f"Fitted {effect}: parameters (SI)",
        "parameter",
        "value",
        names,
        {"fitted": np.array([params[n] for n in names], float)},
        bars=True,
    )


def plot_effect_curve(curve: EffectCurve, path: Path) -> None:
    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    if curve.bars:
        values = curve.curves["fitted"]
        ax.bar(curve.x, values, color="tab:blue")
        for i, value in enumerate(values):
            ax.annotate(f"{value:.4g}", (i, value), ha="center", va="bottom", fontsize=8)
    else:
        for label, y in curve.curves.items():
            ax.plot(
                curve.x,
                y,
                "--" if label == "nominal" else "-",
                color="0.4" if label == "nominal" else None,
                lw=1.2,
                label=label,
            )
        ax.legend(fontsize=8)
    ax.set_title(curve.title, fontsize=9)
    ax.set_xlabel(curve.x_label)
    ax.set_ylabel(curve.y_label)
    ax.grid(alpha=0.3)
    _save(fig, path)


def _friction_curve(effect: str, params: dict[str, float], rig: RigParameters) -> EffectCurve:
    """Static friction torque against velocity: Coulomb level (one per direction), Stribeck peak, viscous."""
    pendulum = effect == "pendulum_friction"
    coulomb = rig.pendulum_coulomb if pendulum else rig.arm_coulomb
    viscous = rig.pendulum_viscous if pendulum else rig.arm_viscous
    velocity = np.linspace(-2.0, 2.0, 801)
    nominal = coulomb * np.sign(velocity) + viscous * velocity
    level_pos = params.get("coulomb_pos", params.get("coulomb", coulomb))
    level_neg = params.get("coulomb_neg", params.get("coulomb", coulomb))
    level = np.where(velocity >= 0, level_pos, level_neg)
    if "static" in params:
        level = level + (params["static"] - level) * np.exp(-((velocity / params["stribeck_velocity"]) ** 2))
    fitted = level * np.sign(velocity) + params.get("viscous", viscous) * velocity
    joint = "pendulum" if pendulum else "arm"
    return EffectCurve(
        effect,
        f"Fitted {effect}: {joint} friction torque",
        f"{joint} velocity [rad/s]",
        "friction torque [N m]",
        velocity,
        {"nominal": nominal, "fitted": fitted},
    )


def _joined(windows: list[WindowResiduals]) -> tuple[np.ndarray, np.ndarray]:
    """The windows in time order, separated by NaN rows (no line across a window boundary), strided to at most
    MAX_PLOT_POINTS samples."""
    if not windows:
        return np.zeros(0), np.zeros((0, 2))
    parts_t, parts_r = [], []
    for w in sorted(windows, key=lambda w: float(w.time[0])):
        parts_t += [np.asarray(w.time, float), [np.nan]]
        parts_r += [np.asarray(w.residual, float), np.full((1, 2), np.nan)]
    time, residual = np.concatenate(parts_t), np.concatenate(parts_r)
    stride = max(1, len(time) // MAX_PLOT_POINTS)
    return time[::stride], residual[::stride]


def _save(fig: Figure, path: Path) -> None:
    fig.tight_layout()
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=110, metadata={"Software": None})


def _canonical(value):
    if isinstance(value, dict):
        return {str(k): _canonical(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return float(f"{value:.{SIGNIFICANT_DIGITS}g}") if math.isfinite(value) else None
    return value


def _require(obj, where: str, keys: dict) -> None:
    if not isinstance(obj, dict):
        raise ValueError(f"report.{where} must be an object")
    for key, types in keys.items():
        if key not in obj:
            raise ValueError(f"report{'.' + where if where else ''} is missing {key!r}")
        value = obj[key]
        if types is _NUMBER:
            if not _is_number(value):
                raise ValueError(f"report.{where}.{key} must be a number, got {value!r}")
        elif not isinstance(value, types):
            raise ValueError(f"report{'.' + where if where else ''}.{key} must be a {types.__name__}")


def _is_number(value) -> bool:
    """Plain numbers; None stands for a non-finite figure (e.g. a diverged candidate's gap)."""
    return value is None or (
        isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    )


def _cell(text: str) -> str:
    """Text for a Markdown table cell (a literal | would end the cell)."""
    return str(text).replace("|", "\\|")


def _fmt(value) -> str:
    return "n/a" if value is None else f"{value:.4g}"


def _percent(value) -> str:
    return "n/a" if value is None else f"{100 * value:.1f} %"
