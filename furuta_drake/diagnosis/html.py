"""``report.html``: the diagnosis report as one self-contained page a person opens in a browser.

The page holds everything inline: CSS in a ``<style>`` element and every PNG figure as a ``data:image/png;base64``
URI, with no script, no external stylesheet, font or image, and no link except in-page ``#anchors``, so it
opens offline and can be mailed as one file. Its order: the verdict (first heading), the gap, the ranking of the
candidates, where the gap is (signals, worst windows, regimes, frequency bands), every figure with its caption,
then any further top-level keys of the report. Optional keys (a ranking entry's ``params_ci``, ``status`` or
``reason``, the localisation's ``after``, ...) are shown when present and skipped when absent.
"""

from __future__ import annotations

import base64
import html
import re
from pathlib import Path

SECTIONS = (
    ("gap", "Gap"),
    ("ranking", "Ranking of the candidates"),
    ("localization", "Where the gap is"),
    ("figures", "Figures"),
)
SHOWN_KEYS = ("verdict", "effects", "gap", "ranking", "localization")  # the rest go to "More"
PERCENT_KEYS = ("heldout_reduction", "share_of_gap", "share_of_samples")
NUMBER = re.compile(r"[-+]?[0-9.]+(e[-+]?[0-9]+)?( %)?")  # a formatted number: right-aligned in its cell
STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 90em; padding: 0 1em; color: #222; }
.scroll { overflow-x: auto; }
h1 { font-size: 1.6em; border-bottom: 2px solid #444; padding-bottom: .3em; }
h2 { margin-top: 2em; border-bottom: 1px solid #bbb; }
table { border-collapse: collapse; margin: .8em 0; font-size: .9em; }
th, td { border: 1px solid #ccc; padding: .25em .6em; text-align: left; vertical-align: top; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
th { background: #f0f0f0; }
code { background: #f4f4f4; padding: 0 .2em; }
figure { margin: 1.5em 0; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-style: italic; margin-top: .3em; }
nav a { margin-right: 1em; }
"""


def report_html(report: dict, directory: Path, figures: dict[str, str]) -> str:
    """The self-contained HTML page of a diagnosis report.

    Parameters
    ----------
    report
        the report as ``report.json`` holds it (``verdict``, ``effects``, ``gap``, ``ranking``,
        ``localization`` and any further keys).
    directory
        the directory holding the figures' PNG files.
    figures
        PNG file name (in ``directory``) -> caption, in the order shown.

    Returns
    -------
    str
        the page; each figure is inlined as a base64 data URI.
    """
    verdict = str(report.get("verdict", "?"))
    body = [
        f"<h1>Verdict: <code>{_text(verdict)}</code></h1>",
        _summary(report),
        "<nav>" + "".join(f'<a href="#{key}">{title}</a>' for key, title in SECTIONS) + "</nav>",
        _gap(report.get("gap", {})),
        _ranking(report.get("ranking", [])),
        _localization(report.get("localization", {})),
        _figures(Path(directory), figures),
    ]
    extra = {key: value for key, value in report.items() if key not in SHOWN_KEYS}
    if extra:
        body.append('<h2 id="more">More</h2>')
        body += [
            f"<h3>{_text(key)}</h3>" + (_any(value) if isinstance(value, (dict, list)) else f"<p>{_any(value)}</p>")
            for key, value in extra.items()
        ]
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>Sim-to-real gap diagnosis: {_text(verdict)}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n"
        + "\n".join(body)
        + "\n</body>\n</html>\n"
    )


def _summary(report: dict) -> str:
    effects = ", ".join(f"<code>{_text(e)}</code>" for e in report.get("effects", [])) or "none"
    gap = report.get("gap", {})
    nominal = gap.get("nominal", {}).get("heldout")
    after = gap.get("with_effects", {}).get("heldout")
    line = f"<p>Accepted effects: {effects}."
    if nominal is not None and after is not None:
        line += (
            f" Held-out gap {_number(nominal)} &rarr; {_number(after)} "
            f"({_percent(gap.get('heldout_reduction'))} reduction)."
        )
    return line + "</p>"


def _gap(gap: dict) -> str:
    parts = ['<h2 id="gap">Gap</h2>']
    if "metric" in gap:
        parts.append(f"<p>Metric: {_text(gap['metric'])}</p>")
    rows = [
        [label, gap[key].get("train"), gap[key].get("heldout")]
        for key, label in (("nominal", "nominal (rig file)"), ("with_effects", "with the accepted effects"))
        if key in gap
    ]
    parts.append(_table(["model", "train", "held-out"], rows))
    rest = {k: v for k, v in gap.items() if k not in ("metric", "nominal", "with_effects")}
    parts += [
        f"<p>{_text(k)}: {_value(k, v)}</p>" if not isinstance(v, (dict, list)) else f"<p>{_text(k)}:</p>{_any(v)}"
        for k, v in rest.items()
    ]
    return "\n".join(parts)


def _ranking(ranking: list[dict]) -> str:
    """Every key any entry has is a column; ``params`` shows ``params_ci`` beside each value when present."""
    keys = list(dict.fromkeys(key for entry in ranking for key in entry if key != "params_ci"))
    rows = []
    for i, entry in enumerate(ranking, 1):
        row = [i]
        for key in keys:
            if key == "params":
                row.append(_Raw(_params(entry.get("params", {}), entry.get("params_ci", {}))))
            else:
                row.append(_Raw(_value(key, entry[key])) if key in entry else "")
        rows.append(row)
    return '<h2 id="ranking">Ranking of the candidates</h2>\n' + _table(["#"] + keys, rows)


def _params(params: dict, intervals: dict) -> str:
    items = []
    for name, value in params.items():
        interval = intervals.get(name)
        ci = (
            f" [{_number(interval[0])}, {_number(interval[1])}]"
            if isinstance(interval, (list, tuple)) and len(interval) == 2
            else ""
        )
        items.append(f"{_text(name)} = {_value(name, value)}{ci}")
    return "<br>".join(items)


def _localization(loc: dict) -> str:
    after = loc.get("after") or {}
    parts = ['<h2 id="localization">Where the gap is</h2>']
    if "basis" in loc:
        parts.append(f"<p>Shares of the {_text(loc['basis'])}.</p>")
    columns = ["nominal"] + (["with the effects"] if after else [])
    signals = loc.get("signals", {})
    parts += [
        "<h3>Signals</h3>",
        _table(
            ["signal"] + [f"share ({c})" for c in columns],
            [
                [name, _Raw(_percent(share))] + ([_Raw(_percent(after.get("signals", {}).get(name)))] if after else [])
                for name, share in signals.items()
            ],
        ),
    ]
    for title, block in (("Worst time windows (nominal model)", loc), ("Worst time windows with the effects", after)):
        if block.get("windows"):
            parts += [f"<h3>{title}</h3>", _records(block["windows"])]
    for key, title, match in (
        ("regimes", "Regimes", ("regime",)),
        ("frequency_bands", "Frequency bands [Hz]", ("low_hz", "high_hz")),
    ):
        rows = [dict(row) for row in loc.get(key, [])]
        after_rows = {tuple(r.get(m) for m in match): r for r in after.get(key, [])}
        for row in rows:
            if after:
                row["share_of_gap (with the effects)"] = after_rows.get(tuple(row.get(m) for m in match), {}).get(
                    "share_of_gap"
                )
        if rows:
            parts += [f"<h3>{title}</h3>", _records(rows)]
    return "\n".join(parts)


def _figures(directory: Path, figures: dict[str, str]) -> str:
    parts = ['<h2 id="figures">Figures</h2>']
    for name, caption in figures.items():
        data = base64.b64encode((directory / name).read_bytes()).decode("ascii")
        parts.append(
            f'<figure id="figure-{_text(Path(name).stem)}"><img src="data:image/png;base64,{data}" '
            f'alt="{_text(caption)}"><figcaption>{_text(caption)} ({_text(name)})</figcaption></figure>'
        )
    return "\n".join(parts)


class _Raw(str):
    """Cell content that is already HTML."""


def _records(rows: list[dict]) -> str:
    keys = list(dict.fromkeys(key for row in rows for key in row))
    return _table(keys, [[_Raw(_value(k, row[k])) if k in row else "" for k in keys] for row in rows])


def _table(header: list[str], rows: list[list]) -> str:
    head = "".join(f"<th>{_text(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(_cell(value) for value in row) + "</tr>\n" for row in rows)
    return f'<div class="scroll"><table>\n<thead><tr>{head}</tr></thead>\n<tbody>\n{body}</tbody>\n</table></div>'


def _cell(value) -> str:
    if isinstance(value, _Raw):
        return f'<td class="num">{value}</td>' if NUMBER.fullmatch(value) else f"<td>{value}</td>"
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return f'<td class="num">{_number(value)}</td>'
    return f"<td>{_text(value)}</td>"


def _value(key: str, value) -> str:
    """HTML of one report value: shares and reductions as percentages, other numbers to 4 digits."""
    if isinstance(value, bool) or value is None:
        return _text("n/a" if value is None else str(value).lower())
    if isinstance(value, (int, float)):
        return _percent(value) if key.startswith(PERCENT_KEYS) else _number(value)
    if isinstance(value, (dict, list)):
        return _any(value)
    return _text(value)


def _any(value) -> str:
    """HTML of any JSON value: a list of objects as a table, an object as a key/value table, else text."""
    if isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
        return _records(value)
    if isinstance(value, list):
        return _text(", ".join(str(v) for v in value)) if value else "-"
    if isinstance(value, dict):
        return _table(["key", "value"], [[k, _Raw(_value(k, v))] for k, v in value.items()])
    return _value("", value)


def _number(value) -> str:
    return "n/a" if value is None else f"{value:.4g}"


def _percent(value) -> str:
    return "n/a" if value is None else f"{100 * value:.1f} %"


def _text(value) -> str:
    return html.escape(str(value), quote=True)


__all__ = ["report_html"]
