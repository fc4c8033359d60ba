"""``report.html``: the diagnosis report as one self-contained page a person opens in a browser.

The page holds everything inline: CSS in a ``<style>`` element, the charts as inline ``<svg>`` and every PNG figure
as a ``data:image/png;base64`` URI, with no script, no external stylesheet, font or image, and no link except
in-page ``#anchors``, so it opens offline and can be mailed as one file.

Its order answers first: the verdict sentence (:func:`~furuta_drake.diagnosis.report.narrative.verdict_sentence`), the
held-out error before and after per log and signal beside what to do next and how far to trust the answer; the
accepted effects as physical statements with their intervals and rig-file lines; what the logs could not see
(the detection limits as a chart); the unmodelled torque when the report has one. Then the evidence: measured
against predicted windows, the steps, the candidate ranking (top entries, the rest folded), where the gap is,
the other figures; the rule and the metric folded at the end, written from the code's constants.
"""

from __future__ import annotations

import base64
import html
import re
from pathlib import Path

from furuta_drake.diagnosis.formatting import number, percent
from furuta_drake.diagnosis.report import narrative, tables
from furuta_drake.diagnosis.report.charts import chart_svgs

STYLE = """
body { font-family: system-ui, sans-serif; margin: 0 auto; max-width: 1200px; padding: 12px 20px; color: #222;
       line-height: 1.4; }
.kicker { color: #555; margin: 0; font-size: .95em; }
h1.verdict { font-size: 1.35em; font-weight: 600; margin: .3em 0 .6em; padding: .6em .8em; background: #eef4fb;
             border-left: 6px solid #1f6fb4; }
h1.verdict.none { background: #eef8ee; border-color: #3a8f3a; }
h1.verdict.unexplained { background: #fdf3e6; border-color: #d9822b; }
.first { display: grid; grid-template-columns: minmax(0, 1.15fr) minmax(0, 1fr); gap: 20px; }
h2 { font-size: 1.15em; margin: 1.4em 0 .4em; border-bottom: 1px solid #ccc; }
.first h2 { margin-top: 0; }
h3 { font-size: 1em; margin: 1em 0 .3em; }
ol.next { padding-left: 1.2em; margin: .3em 0; }
ol.next li { margin-bottom: .45em; }
code, pre { background: #f3f3f3; font-size: .88em; }
td code { background: none; }
pre { padding: .3em .5em; margin: .2em 0; white-space: pre-wrap; overflow-wrap: anywhere; }
.scroll { overflow-x: auto; max-width: 100%; }
table { border-collapse: collapse; margin: .5em 0; font-size: .88em; }
th, td { border: 1px solid #ccc; padding: .25em .5em; text-align: left; vertical-align: top; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
th { background: #f0f0f0; }
svg { max-width: 100%; height: auto; }
figure { margin: 1em 0; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: .9em; color: #444; }
details { margin: .6em 0; }
summary { cursor: pointer; font-weight: 600; }
.muted { color: #666; font-size: .9em; }
"""


def report_html(report: dict, directory: Path, figures: dict[str, str]) -> str:
    """The self-contained HTML page of a diagnosis report.

    Parameters
    ----------
    report
        the report as ``report.json`` holds it (the spec's keys and any later ones; optional ones may be absent).
    directory
        the directory holding the figures' files.
    figures
        file name (in ``directory``; ``.svg`` inlined as SVG, others as base64 PNG) -> caption, in the order shown.

    Returns
    -------
    str
        the page.
    """
    directory = Path(directory)
    charts = chart_svgs(report)
    body = [
        f'<p class="kicker">Sim-to-real gap diagnosis · verdict <code>{_text(report["verdict"])}</code></p>',
        f'<h1 class="verdict {_text(report["verdict"])}" id="verdict">{_text(narrative.verdict_sentence(report))}</h1>',
        _remaining(report),
        _first_screen(report, charts),
        _effects(report),
        _gap_left(report, directory),
        _limits(report, charts),
        '<h2 id="evidence">The evidence</h2>',
        _windows(directory, figures),
        _steps(report),
        _ranking(report),
        _localization(report, charts),
        _figures(directory, {k: v for k, v in figures.items() if k != "windows.svg"}),
        _rule(report),
        _notes(report),
    ]
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f'<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>Sim-to-real gap diagnosis: {_text(report['verdict'])}</title>\n<style>{STYLE}</style>\n</head>\n"
        "<body>\n" + "\n".join(part for part in body if part) + "\n</body>\n</html>\n"
    )


def _remaining(report: dict) -> str:
    """What the accepted effects leave, under the verdict (nothing when it is negligible), and the rig's
    disturbance."""
    sentences = narrative.remaining_sentences(report)
    disturbance = narrative.disturbance_sentence(report)
    out = f'<p class="remaining" id="remaining">{_text(" ".join(sentences))}</p>' if sentences else ""
    return out + (f'\n<p class="disturbance" id="disturbance">{_text(disturbance)}</p>' if disturbance else "")


def _first_screen(report: dict, charts: dict[str, str]) -> str:
    gap = report["gap"]
    headline = (
        f"Held-out gap {number(gap['nominal']['heldout'], 3)} counts with the rig file"
        + (
            f", {number(gap['with_effects']['heldout'], 3)} with the accepted effects "
            f"({percent(gap['heldout_reduction'])} less)"
            if report.get("effects")
            else ""
        )
        + "."
    )
    picture = (
        '<section class="picture"><h2 id="before-after">Held-out error, before and after</h2>'
        f'{inline_svg(charts["gap.svg"])}<p class="muted">{_text(headline)} Logs the fit never saw.</p></section>'
    )
    items = "".join(
        f"<li>{_text(what)}{':' if command else '.'}" + (f"<pre>{_text(command)}</pre>" if command else "") + "</li>"
        for what, command in narrative.next_steps(report)
    )
    trust_html = "".join(f"<p>{_text(sentence)}</p>" for sentence in narrative.trust_sentences(report))
    side = (
        '<section class="next"><h2 id="next">What to do next</h2>'
        f'<p class="muted">Commands run from this report\'s folder.</p><ol class="next">{items}</ol>'
        f'<h3 id="trust">How far to trust it</h3>{trust_html}</section>'
    )
    return f'<div class="first">{picture}{side}</div>'


def _effects(report: dict) -> str:
    header, rows = tables.effects_table(report)
    if not rows:
        return ""
    return (
        '<h2 id="effects">The accepted effects</h2>'
        + _table(
            header,
            [[_Raw(f"<code>{_text(r[0])}</code>"), r[1], r[2], _Raw(f"<code>{_text(r[3])}</code>")] for r in rows],
        )
        + '<p class="muted">The lines go under <code>effects:</code> in the rig file; <code>fitted_rig.yaml</code> '
        "holds them already.</p>"
    )


def _gap_left(report: dict, directory: Path) -> str:
    """For an unexplained verdict, what the gap is; the unmodelled torque and the listed effects kept beside it
    when the report has them."""
    parts = []
    if report["verdict"] == "unexplained":
        parts += [
            '<h2 id="gap-left">What the gap is</h2>',
            f"<p>{_text(narrative.where_sentence(report['localization']))} "
            'The charts under <a href="#localization">Where the gap is</a> show it by signal, regime and band.</p>',
        ]
    torque = report.get("unmodelled_torque")
    if torque:
        parts += ['<h2 id="unmodelled-torque">The unmodelled torque</h2>', *_unmodelled(torque, directory)]
    header, rows = tables.beside_table(report)
    if rows:
        parts += [
            '<h2 id="beside-torque">The listed effects beside the torque</h2>',
            f"<p>{_text(tables.beside_sentence(report))}</p>",
            _table(
                header, [[_Raw(f"<code>{_text(r[0])}</code>"), r[1], _Raw(f"<code>{_text(r[2])}</code>")] for r in rows]
            ),
        ]
    return "\n".join(parts)


def _unmodelled(torque: dict, directory: Path) -> list[str]:
    parts = []
    for joint, fit in torque.items():
        parts += [f"<p>{_text(tables.unmodelled_sentence(joint, fit))}</p>", _table(*tables.unmodelled_table(fit))]
        plot = fit.get("plot")
        if plot and (directory / plot).is_file():
            parts.append(_figure(directory, plot, f"Unmodelled torque on the {joint}"))
    return parts


def _limits(report: dict, charts: dict[str, str]) -> str:
    limits = report.get("detection_limits", [])
    if not limits:
        return ""
    intro = (
        "No effect larger than these would have gone unseen in these logs"
        if report["verdict"] == "none"
        else "Effects not accepted would have been detected at these sizes"
    )
    items = "".join(f"<li>{_text(narrative.limit_sentence(limit))}.</li>" for limit in limits)
    return (
        '<h2 id="limits">What these logs could not see</h2>'
        f"<p>{intro} (each injected into the model's own prediction of the held-out windows and judged by the "
        "same rule); below these sizes an effect could hide:</p>"
        f"{inline_svg(charts['detection_limits.svg'])}<details><summary>In words</summary><ul>{items}</ul></details>"
    )


def _windows(directory: Path, figures: dict[str, str]) -> str:
    if "windows.svg" not in figures:
        return ""
    return "<h3>Measured against predicted, held-out windows</h3>" + _figure(
        directory, "windows.svg", figures["windows.svg"]
    )


def _steps(report: dict) -> str:
    header, rows = tables.steps_table(report)
    return '<h3 id="steps">One row per accepted step</h3>' + _table(header, rows) if rows else ""


def _ranking(report: dict) -> str:
    (header, shown), (_, folded), failed, screened = tables.ranking_tables(report)
    text = (
        '<h3 id="ranking">Candidates tried</h3><p class="muted">'
        f"The best {tables.TOP_PER_STEP} of each step; each row names the effect its step added to the earlier "
        "ones.</p>" + _table(header, shown)
    )
    if folded:
        text += f"<details><summary>The other {len(folded)} candidates</summary>{_table(header, folded)}</details>"
    if failed:
        items = "".join(f"<li>{_text(line)}</li>" for line in failed)
        text += f"<details><summary>{len(failed)} failed candidates (left out)</summary><ul>{items}</ul></details>"
    if screened:
        items = "".join(f"<li>{_text(line)}</li>" for line in screened)
        text += f"<details><summary>{len(screened)} candidates screened out</summary><ul>{items}</ul></details>"
    return text


def _localization(report: dict, charts: dict[str, str]) -> str:
    loc = report.get("localization", {})
    parts = ['<h3 id="localization">Where the gap is</h3>', f"<p>{_text(narrative.where_sentence(loc))}</p>"]
    if "localization.svg" in charts:
        parts += [
            inline_svg(charts["localization.svg"]),
            '<p class="muted">Shares of the '
            + _text(loc.get("basis", "excess squared residual"))
            + "; grey: the rig file, blue: with the accepted effects; the black tick is the regime's share of the "
            "samples (regimes overlap).</p>",
        ]
    header, rows = tables.windows_table(loc)
    if rows:
        parts.append(f"<details><summary>The worst time windows (rig file)</summary>{_table(header, rows)}</details>")
    return "\n".join(parts)


def _figures(directory: Path, figures: dict[str, str]) -> str:
    if not figures:
        return ""
    return '<h3 id="figures">More figures</h3>' + "".join(
        _figure(directory, name, caption) for name, caption in figures.items()
    )


def _figure(directory: Path, name: str, caption: str) -> str:
    path = directory / name
    if name.endswith(".svg"):
        content = inline_svg(path.read_text())
    else:
        data = base64.b64encode(path.read_bytes()).decode("ascii")
        content = f'<img src="data:image/png;base64,{data}" alt="{_text(caption)}">'
    return f'<figure id="figure-{_text(Path(name).stem)}">{content}<figcaption>{_text(caption)}</figcaption></figure>'


def _rule(report: dict) -> str:
    parts = [
        '<details id="rule"><summary>How the verdict is reached: the rule and the metric</summary>',
        _table(*tables.rule_table()),
        f"<p>{_text(report.get('rule', ''))}</p>" if report.get("rule") else "",
        f"<p><b>Metric.</b> {_text(report['gap'].get('metric', ''))}"
        + (f" ({_text(report['gap']['evaluated_by'])})" if report["gap"].get("evaluated_by") else "")
        + ".</p>",
        f"<p><b>Held-out data.</b> {_text(report['holdout'])}.</p>" if report.get("holdout") else "",
        f"<p><b>Intervals.</b> {_text(report['uncertainty'])}.</p>" if report.get("uncertainty") else "",
        f"<p><b>Why this verdict.</b> {_text(report['choice'])}</p>" if report.get("choice") else "",
        "</details>",
    ]
    return "\n".join(part for part in parts if part)


def _notes(report: dict) -> str:
    notes = report.get("notes") or []
    return "<h3>Notes</h3><ul>" + "".join(f"<li>{_text(n)}</li>" for n in notes) + "</ul>" if notes else ""


class _Raw(str):
    """Cell content that is already HTML."""


NUMBER = re.compile(r"[-+]?[0-9.]+(e[-+]?[0-9]+)?( %)?( \[.*\])?")  # a formatted figure: right-aligned


def _table(header: list[str], rows: list[list]) -> str:
    head = "".join(f"<th>{_text(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(_cell(value) for value in row) + "</tr>\n" for row in rows)
    return f'<div class="scroll"><table>\n<thead><tr>{head}</tr></thead>\n<tbody>\n{body}</tbody>\n</table></div>'


def _cell(value) -> str:
    if isinstance(value, _Raw):
        return f'<td class="num">{value}</td>' if NUMBER.fullmatch(value) else f"<td>{value}</td>"
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return f'<td class="num">{number(value)}</td>'
    return f"<td>{_text(number(None) if value is None else value)}</td>"


SVG_DROPPED = (
    re.compile(r"<\?xml[^>]*>\s*"),
    re.compile(r"<!DOCTYPE[^>]*>\s*"),
    re.compile(r"<metadata>.*?</metadata>\s*", re.S),
    re.compile(r'\s+xmlns(:\w+)?="[^"]*"'),
)


def inline_svg(text: str) -> str:
    """An SVG file's text as an element of the page: no prologue, metadata or namespace URIs (HTML's parser
    gives inline ``<svg>`` its namespace)."""
    for pattern in SVG_DROPPED:
        text = pattern.sub("", text)
    return text.strip()


def _text(value) -> str:
    return html.escape(str(value), quote=True)


__all__ = ["report_html", "inline_svg"]
