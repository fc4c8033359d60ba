"""The design's output directory: ``experiment.csv`` (the command to play), ``design.json``, ``design.md``,
``design.png`` and ``config.yaml``; ``docs/design.md`` describes each. Written through
:func:`~furuta_drake.outputs.atomic_output_dir`: it appears complete or not at all. Without a design (no
experiment separates the hypotheses, or none stays within the bounds) there is no ``experiment.csv`` nor plot,
and ``design.json`` says why.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import yaml
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from furuta_drake.design.pipeline import Design
from furuta_drake.design.torque_hypothesis import describe_effect
from furuta_drake.outputs import atomic_output_dir, versions
from furuta_drake.rig import encoder_resolution

SIGNIFICANT_DIGITS = 6


def write_design(out_dir: str | Path, design: Design, *, force: bool = False) -> Path:
    """Write every file of ``design`` into ``out_dir`` atomically; the diagnosis directory and its inputs are
    protected from ``force``."""
    record = design.record
    protect = [record.directory, record.rig_path, *(Path(log.path) for log in record.train + record.heldout)]
    with atomic_output_dir(out_dir, force=force, protect=protect) as staging:
        document = design_json(design)
        (staging / "design.json").write_text(json.dumps(_rounded(document), indent=2, allow_nan=False) + "\n")
        if design.command is not None:
            (staging / "experiment.csv").write_text(experiment_csv(design))
            plot_design(design, staging / "design.png")
        (staging / "design.md").write_text(design_markdown(document))
        (staging / "config.yaml").write_text(yaml.safe_dump(_config(design), sort_keys=False))
    return Path(out_dir)


def _unit(design: Design) -> tuple[str, str]:
    return ("voltage", "V") if design.input_kind == "voltage" else ("torque", "N m")


def experiment_csv(design: Design) -> str:
    """A comment line saying how to play it, then ``time`` and the rig's input column at its sample period."""
    column, unit = _unit(design)
    values = design.command / design.torque_per_volt
    period = design.period
    if design.mode == "balancing":
        gain = ", ".join(f"{v:.6g}" for v in design.excitation["lqr_gain"])
        how = (
            f"# dither [{unit}] to ADD to the output of furuta-drake's LQR balancing the pendulum upright (gain "
            f"K = [{gain}] on [theta, phi, theta_dot, phi_dot], designed on the rig file), from rest upright, "
            f"one value per {period:g} s sample; then stop the dither"
        )
    else:
        how = (
            f"# open-loop command [{unit}]: play it as is from rest with the pendulum hanging, one value per "
            f"{period:g} s sample, then zero"
        )
    rows = "".join(f"{k * period:.6f},{value + 0.0:.6g}\n" for k, value in enumerate(values))
    return f"{how}\ntime,{column}\n{rows}"


def design_json(design: Design) -> dict:
    """The ``design.json`` object (docs/design.md lists every key)."""
    column, unit = _unit(design)
    scale = 1.0 / design.torque_per_volt
    nominal = design.hypotheses.nominal
    out = {
        "status": design.status,
        "reason": design.reason,
        "mode": design.mode,
        "duration_s": design.duration,
        "sample_period_s": design.period,
        "input": {
            "column": column,
            "unit": unit,
            "limit": design.bounds.command * scale,
            "file": "experiment.csv" if design.command is not None else None,
        },
        "hypotheses": [
            {
                "name": h.name,
                "role": h.role,
                "effects": {name: describe_effect(name, effect, nominal) for name, effect in h.effects.items()},
            }
            for h in design.hypotheses.hypotheses
        ],
        "pairs": design.pairs,
        "detection_limits": design.limits,
        "responses": {
            name: {
                "peak_arm_angle_rad": run.peaks["arm"],
                "peak_pendulum_excursion_rad": run.peaks["pendulum"],
                f"peak_command_{unit.replace(' ', '_')}": run.peaks["command"] * scale,
                "evaluated_by": "drake",
            }
            for name, run in design.runs.items()
        },
        "bounds": {
            "arm_angle_rad": design.bounds.arm,
            "pendulum_excursion_rad": design.bounds.pendulum,
            f"command_{unit.replace(' ', '_')}": design.bounds.command * scale,
        },
        "excitation": design.excitation,
        "seed": design.settings.seed,
        "search": design.search,
        "notes": design.notes,
    }
    if design.choice:
        out["choice"] = design.choice
    return out


def _config(design: Design) -> dict:
    record = design.record
    return {
        "diagnosis": {"path": str(record.directory), "report_sha256": record.report_sha256},
        "rig": record.inputs["rig"],
        "train": record.inputs["train"],
        "heldout": record.inputs["heldout"],
        "options": design.options,
        "versions": versions(),
        "seeds": {"search": design.settings.seed, "noise": design.settings.seed},
    }


def design_markdown(document: dict) -> str:
    """design.md: the same content for a person."""
    lines = ["# Experiment design", ""] + _md_experiment(document) + _md_hypotheses(document)
    lines += _md_pairs(document) + _md_limits(document) + _md_choice(document) + _md_responses(document)
    bounds, unit = document["bounds"], document["input"]["unit"]
    lines += [
        "",
        f"Bounds under every hypothesis: arm angle {_fmt(bounds['arm_angle_rad'])} rad, pendulum "
        f"excursion {_fmt(bounds['pendulum_excursion_rad'])} rad, command "
        f"{_fmt(next(v for k, v in bounds.items() if k.startswith('command')))} {unit}.",
        "",
    ]
    lines += _md_excitation(document)
    if document["notes"]:
        lines += ["", "## Notes", ""] + [f"- {note}" for note in document["notes"]]
    return "\n".join(lines) + "\n"


def _md_experiment(document: dict) -> list[str]:
    """What to play and how, or why there is no experiment."""
    if document["status"] != "design":
        return [f"**No experiment** ({document['status']}): {document['reason']}.", ""]
    how = (
        "a dither added to the LQR balancing the upright"
        if document["mode"] == "balancing"
        else "played open loop from rest with the pendulum hanging"
    )
    return [
        f"`experiment.csv`: {document['duration_s']:g} s of `{document['input']['column']}` "
        f"[{document['input']['unit']}], "
        f"{how}, one value per {document['sample_period_s']:g} s. Record it like the diagnosis' logs, "
        f"then run the diagnosis again with its first half added to `--train` and its second half to "
        f"`--heldout`.",
        "",
        "![command and predicted responses](design.png)",
        "",
    ]


def _md_hypotheses(document: dict) -> list[str]:
    lines = ["## Hypotheses", "", "| hypothesis | role | effects |", "|---|---|---|"]
    for h in document["hypotheses"]:
        effects = (
            "; ".join(
                f"{name}: " + ", ".join(f"{k} = {_fmt(v)}" for k, v in params.items())
                for name, params in h["effects"].items()
            )
            or "-"
        )
        lines.append(f"| `{h['name']}` | {h['role']} | {effects} |")
    return lines


def _md_pairs(document: dict) -> list[str]:
    """The pairs the experiment separates, per direction, and why each pair was a question."""
    if not document["pairs"]:
        return []
    lines = [
        "",
        "## What the experiment separates",
        "",
        "| truth | rival | noncentrality | held-out gap difference [counts] (90 %) | detection probability |",
        "|---|---|---:|---:|---:|",
    ]
    for pair in document["pairs"]:
        for d in pair["directions"]:
            diff = d["gap_difference_all_heldout"]
            lines.append(
                f"| `{d['truth']}` | `{d['rival']}` | {_fmt(d['noncentrality'])} | "
                f"{_fmt(diff['median'])} [{_fmt(diff['interval90'][0])}, {_fmt(diff['interval90'][1])}]"
                f" | {d['detection_probability']:.0%} |"
            )
    lines += [
        "",
        "The noncentrality is the expected log-likelihood ratio of the experiment's held-out half "
        "under the truth's encoder noise, once the rival is refit and every window's initial state "
        "re-projected; the gap difference (rival minus truth) is over all held-out windows the new "
        "diagnosis would judge; the detection probability is the share of noise draws in which its rule "
        "picks the truth and no longer finds the two confusable.",
        "",
    ]
    return lines + [
        f"- `{pair['hypotheses'][0]}` vs `{pair['hypotheses'][1]}`: {pair['why']}" for pair in document["pairs"]
    ]


def _md_limits(document: dict) -> list[str]:
    """Per targeted effect: the size that matters, today's detection limit and the predicted one."""
    if not document["detection_limits"]:
        return []
    lines = [
        "",
        "## Detection limits",
        "",
        "| effect | size that matters | limit today | predicted with the experiment | falls to the size |",
        "|---|---:|---:|---:|---|",
    ]
    for limit in document["detection_limits"]:
        unit, below = limit["unit"], limit["predicted_below_size"]
        lines.append(
            f"| `{limit['effect']}` ({limit['param']}) | {_fmt(limit['size'])} {unit} | "
            f"{_limit(limit['today'], unit)} | {_limit(limit['predicted'], unit)} | "
            f"{'-' if below is None else 'yes' if below else 'no'} |"
        )
    return lines + [
        "",
        "A limit is the smallest size the acceptance rule detects on the held-out windows, the effect injected "
        "into the accepted model's prediction (the report's detection limits); the predicted one adds the "
        "experiment's held-out half as the accepted model plays it. A real fit must also find the parameter, so "
        "a real detection needs somewhat more.",
    ]


def _md_choice(document: dict) -> list[str]:
    """The candidate experiments compared by their predicted limits, why one was chosen and what a longer one of
    its mode would reach."""
    choice = document.get("choice")
    if not choice:
        return []
    units = {limit["effect"]: limit["unit"] for limit in document["detection_limits"]}
    lines = [
        "",
        "## Which experiment",
        "",
        "| mode | duration [s] | predicted limits (shortfall) | chosen |",
        "|---|---:|---|---|",
    ]
    for c in choice["candidates"]:
        limits = "; ".join(
            f"`{t['effect']}` {_limit(t['predicted'], units[t['effect']])} ({_fmt(t['shortfall'])})"
            for t in c["detection_limits"]
        )
        mode = "open loop, hanging" if c["mode"] == "hanging" else "dither on the LQR, balancing"
        lines.append(
            f"| {mode} | {c['duration_s']:g} | {limits or c['status'] + ': ' + c['reason']} | "
            f"{'yes' if c['chosen'] else ''} |"
        )
    lines += ["", f"Criterion: {choice['criterion']}. Chosen: {choice['why']}."]
    return lines + [line for longer in choice["longer"] for line in ("", _md_longer(longer))]


def _md_longer(longer: dict) -> str:
    """What a longer experiment of the chosen mode would bring a target's limit to."""
    kind = "an open-loop" if longer["mode"] == "hanging" else "a balancing"
    unit, size, reaching = longer["unit"], longer["size"], longer["duration_reaching_size_s"]
    measured = ", ".join(f"{_limit(v, unit)} at {d:g} s" for d, v in zip(longer["durations_s"], longer["predicted"]))
    if reaching is not None:
        return (
            f"{kind.capitalize()} experiment of about {reaching:.3g} s would bring the `{longer['effect']}` "
            f"detection limit to its size, {_fmt(size)} {unit} (predicted: {measured}; the shortfall extrapolated "
            f"as the duration to the power {longer['exponent']:.2f})."
        )
    if longer["exponent"] is None:
        return f"The `{longer['effect']}` limit's scaling with the duration was not measured ({measured})."
    return (
        f"No {kind.split(' ')[1]} experiment of any duration is predicted to bring the `{longer['effect']}` "
        f"detection limit to {_fmt(size)} {unit}: it does not fall with the duration ({measured})."
    )


def _limit(value, unit: str) -> str:
    return "not reached" if value is None else f"{_fmt(value)} {unit}"


def _md_responses(document: dict) -> list[str]:
    if not document["responses"]:
        return []
    lines = [
        "",
        "## Predicted responses (Drake)",
        "",
        "| hypothesis | peak arm angle [rad] | peak pendulum excursion [rad] | peak command "
        f"[{document['input']['unit']}] |",
        "|---|---:|---:|---:|",
    ]
    for name, r in document["responses"].items():
        command = next(v for k, v in r.items() if k.startswith("peak_command"))
        lines.append(
            f"| `{name}` | {_fmt(r['peak_arm_angle_rad'])} | {_fmt(r['peak_pendulum_excursion_rad'])} "
            f"| {_fmt(command)} |"
        )
    return lines


def _md_excitation(document: dict) -> list[str]:
    excitation = document["excitation"]
    if not excitation.get("bands"):
        return []
    lines = [
        "## Excitation",
        "",
        f"{excitation['family']}; fundamental "
        f"{_fmt(excitation['fundamental_hz'])} Hz, "
        f"{_fmt(excitation['periods'])} periods, ramps of {_fmt(excitation['ramp_s'])} s, "
        f"{excitation['phases']} phases; seed {document['seed']}.",
        "",
        "| band [Hz] | components | amplitude |",
        "|---|---:|---:|",
    ]
    for band in excitation["bands"]:
        amplitude = next(
            (f"{_fmt(v)} {k.split('_', 1)[1].replace('_', ' ')}" for k, v in band.items() if k.startswith("amplitude")),
            "",
        )
        lines.append(f"| {_fmt(band['low_hz'])}-{_fmt(band['high_hz'])} | {band['components']} | {amplitude} |")
    return lines


def plot_design(design: Design, path: Path) -> None:
    """The command, and the arm angle, the pendulum's excursion and the arm angle's departure from the accepted
    hypothesis [counts] under every hypothesis (Drake runs), overlaid."""
    _, unit = _unit(design)
    fig = Figure(figsize=(10, 9))
    axes = fig.subplots(4, 1, sharex=True)
    time = np.arange(design.command.size) * design.period
    axes[0].plot(time, design.command / design.torque_per_volt, color="k", lw=0.7)
    axes[0].set_ylabel(f"{'dither' if design.mode == 'balancing' else 'command'} [{unit}]")
    rest = 0.0 if design.mode == "balancing" else np.pi
    count = encoder_resolution(design.record.rig.counts_per_rev)
    reference = design.runs.get(design.hypotheses.hypotheses[0].name)
    for name, run in design.runs.items():
        axes[1].plot(run.time, run.angles[:, 1], lw=0.8, label=name)
        axes[2].plot(run.time, run.angles[:, 0] - rest, lw=0.8)
        if reference is not None:
            n = min(run.time.size, reference.time.size)
            axes[3].plot(run.time[:n], (run.angles[:n, 1] - reference.angles[:n, 1]) / count, lw=0.8)
    for ax, bound in ((axes[1], design.bounds.arm), (axes[2], design.bounds.pendulum)):
        for sign in (-1, 1):
            ax.axhline(sign * bound, color="r", lw=0.6, ls=":")
    axes[1].set_ylabel("arm angle phi [rad]")
    axes[2].set_ylabel("pendulum from " + ("upright" if design.mode == "balancing" else "hanging") + " [rad]")
    axes[3].set_ylabel("phi - phi(accepted) [counts]")
    axes[3].set_xlabel("time [s]")
    axes[1].legend(fontsize=7, loc="upper right")
    for ax in axes:
        ax.axvline(design.duration / 2, color="0.6", lw=0.6, ls="--")
    axes[0].set_title("designed experiment (dashed: train | held-out halves) and its predicted responses")
    fig.tight_layout()
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=110)


def _rounded(value):
    """Floats to SIGNIFICANT_DIGITS significant digits (non-finite as null), recursively."""
    if isinstance(value, dict):
        return {key: _rounded(v) for key, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_rounded(v) for v in value]
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return float(f"{value:.{SIGNIFICANT_DIGITS}g}") if math.isfinite(value) else None
    if isinstance(value, (np.integer, np.bool_)):
        return value.item()
    return value


def _fmt(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, str):
        return value
    return f"{value:.4g}"
