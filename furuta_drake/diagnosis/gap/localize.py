"""Where the gap lives (spec ``localization``): which signal, which time windows, which regimes, which frequency
bands carry the prediction residuals, before and after adding the accepted effects.

Everything is a share of the *excess* squared residual: r^2 minus the sensor variance the model expects
(1/12 count^2 for the rig's encoder), so a model that sits at its sensor floor has nothing to localise. When a
residual set has no excess at all (total r^2 within the sensor floor) the shares are of the raw r^2 instead; the
``basis`` key says which. Keys extend the spec's object (``share_of_samples``, ``definition``, ``share_of_gap``
per window, ``basis``, ``after``); none is renamed.

- ``signals``: each signal's excess (clipped at 0) over both signals' excess.
- ``regimes``: the excess in the samples of a regime over the total excess (clipped to [0, 1]), next to the
  regime's share of the samples, so over-representation shows (regimes overlap: shares need not add to 1).
  The regimes read the predicted state of each window: arm velocity reversal (phi_dot changes sign within
  +-``REVERSAL_WINDOW_S``), near-zero and high arm speed (fractions of the 90th percentile of |phi_dot| over the
  ``before`` samples, the same thresholds after), upright / hanging / swinging (|theta| or |theta - pi| wrapped
  below 0.5 rad) and torque saturation (the command at the rig's limit).
- ``frequency_bands``: per window, the rectangular-window periodogram of each signal's residual (Parseval:
  bin powers sum to the window's r^2), each bin's power spread over the bands by the overlap of its frequency
  interval [f - df/2, f + df/2]; white sensor noise of variance s^2 puts s^2 (2 s^2 off DC and Nyquist) in every
  bin, which is subtracted. Windows of length T resolve 1/T Hz: with 0.2-0.3 s windows the 0-1 and 1-3 Hz bands
  share the DC bin's power.
- ``windows``: the prediction windows with the largest excess, taken until they hold half of the positive
  excess and while they hold at least half the worst one's (at most ``MAX_WORST``), merged where they touch or
  overlap in the same log, reported worst first with a ``why`` from the dominant signal, motion regimes, pose
  and band of the interval.
"""

from __future__ import annotations

import math

import numpy as np

from furuta_drake.diagnosis.logs.load import WindowResiduals

BAND_EDGES_HZ = (0.0, 1.0, 3.0, 10.0, 30.0)  # the last band runs to the Nyquist frequency
REVERSAL_WINDOW_S = 0.05  # a sample is "at a reversal" within this time of a sign change of phi_dot [s]
NEAR_ZERO_FRACTION = 0.1  # |phi_dot| below this fraction of its 90th percentile: near-zero arm speed
HIGH_SPEED_FRACTION = 0.5  # |phi_dot| above this fraction of its 90th percentile: high arm speed
POSE_RADIUS = 0.5  # [rad] upright |theta| < 0.5, hanging |theta - pi| < 0.5 (wrapped)
WORST_SHARE = 0.5  # worst windows are taken until they hold this share of the positive excess
MAX_WORST = 8  # at most this many windows are taken, and at most this many merged intervals reported
SENSOR_VARIANCE = 1.0 / 12.0  # [count^2] uniform quantisation of the rig's encoder

REGIMES = (
    "arm velocity reversal",
    "near-zero arm speed",
    "high arm speed",
    "upright",
    "hanging",
    "swinging",
    "torque saturation",
)
_POSES = ("upright", "hanging", "swinging")
_MOTIONS = ("arm velocity reversal", "near-zero arm speed", "high arm speed", "torque saturation")
_PHRASES = {
    "arm velocity reversal": "at arm velocity reversals",
    "near-zero arm speed": "at near-zero arm speed",
    "high arm speed": "at high arm speed",
    "torque saturation": "with the torque saturated",
    "upright": "near upright",
    "hanging": "hanging",
    "swinging": "swinging",
}


def localize(
    before: list[WindowResiduals],
    after: list[WindowResiduals] | None = None,
    *,
    noise_variance: float = SENSOR_VARIANCE,
    noise_variance_after: float | None = None,
) -> dict:
    """The spec's ``localization`` object for the nominal residuals ``before``, with the same analysis of the
    residuals with the accepted effects under ``after`` when given.

    ``noise_variance`` [count^2 per signal] is the sensor variance the nominal model expects;
    ``noise_variance_after`` that of the model with the effects (default: the same).
    """
    if not before:
        raise ValueError("localize needs at least one window of residuals")
    speed_scale = float(np.percentile(np.abs(np.concatenate([w.state[:, 3] for w in before])), 90))
    result = _localize_set(before, noise_variance, speed_scale)
    if after is not None:
        variance = noise_variance if noise_variance_after is None else noise_variance_after
        result["after"] = _localize_set(after, variance, speed_scale)
    return result


def dominant(localization: dict) -> dict:
    """Where most of a localised gap sits: the signal holding the largest share (``signal``, its ``signal_share``),
    the regime most over-represented (``regime``: the largest share of the gap over share of the samples, with its
    ``regime_share`` and ``regime_samples``) and the band holding the largest share (``band_hz`` [low, high],
    ``band_share``); a key is None where the localisation has nothing to read."""
    signals = localization.get("signals") or {}
    signal = max(signals, key=lambda s: signals[s] or 0.0) if signals else None
    regimes = [r for r in localization.get("regimes", []) if (r.get("share_of_samples") or 0) > 0]
    regime = max(regimes, key=lambda r: (r["share_of_gap"] or 0.0) / r["share_of_samples"]) if regimes else None
    bands = localization.get("frequency_bands", [])
    band = max(bands, key=lambda b: b["share_of_gap"] or 0.0) if bands else None
    return {
        "signal": signal,
        "signal_share": signals[signal] if signal else None,
        "regime": regime["regime"] if regime else None,
        "regime_share": regime["share_of_gap"] if regime else None,
        "regime_samples": regime["share_of_samples"] if regime else None,
        "band_hz": [band["low_hz"], band["high_hz"]] if band else None,
        "band_share": band["share_of_gap"] if band else None,
    }


def regime_masks(window: WindowResiduals, speed_scale: float, reversals: np.ndarray) -> dict[str, np.ndarray]:
    """Boolean sample masks of :data:`REGIMES` for one window; ``speed_scale`` is the 90th percentile of
    |phi_dot| [rad/s] that the speed regimes are fractions of, ``reversals`` the sorted times [s] at which the
    predicted phi_dot of the window's log changes sign (:func:`reversal_times`)."""
    theta, phi_dot = window.state[:, 0], window.state[:, 3]
    speed = np.abs(phi_dot)
    upright = np.abs(_wrap(theta)) < POSE_RADIUS
    hanging = np.abs(_wrap(theta - math.pi)) < POSE_RADIUS
    return {
        "arm velocity reversal": _near(window.time, reversals, REVERSAL_WINDOW_S),
        "near-zero arm speed": speed < NEAR_ZERO_FRACTION * speed_scale,
        "high arm speed": speed > HIGH_SPEED_FRACTION * speed_scale,
        "upright": upright,
        "hanging": hanging,
        "swinging": ~(upright | hanging),
        "torque saturation": np.asarray(window.saturated, bool),
    }


def band_power(window: WindowResiduals, noise_variance: float, edges_hz=BAND_EDGES_HZ) -> tuple[np.ndarray, np.ndarray]:
    """(band edges [Hz] ending at Nyquist, excess residual power per band and signal (bands x 2) [count^2])
    of one window: periodogram bins minus the white sensor noise, spread over the bands by overlap."""
    n = len(window.time)
    dt = float(np.median(np.diff(window.time))) if n > 1 else 1.0
    nyquist = 0.5 / dt
    edges = np.array([e for e in edges_hz if e < nyquist] + [nyquist])
    spectrum = np.fft.rfft(np.asarray(window.residual, float), axis=0)
    weight = np.full(spectrum.shape[0], 2.0)
    weight[0] = 1.0
    if n % 2 == 0:
        weight[-1] = 1.0
    power = weight[:, None] * np.abs(spectrum) ** 2 / n - weight[:, None] * noise_variance
    df = 1.0 / (n * dt)
    freq = np.arange(spectrum.shape[0]) * df
    low = np.clip(freq - df / 2, 0.0, nyquist)
    high = np.clip(freq + df / 2, 0.0, nyquist)
    overlap = np.clip(
        np.minimum(high[:, None], edges[None, 1:]) - np.maximum(low[:, None], edges[None, :-1]), 0.0, None
    )
    fraction = overlap / np.maximum(high - low, 1e-300)[:, None]  # bins x bands, rows sum to 1
    return edges, fraction.T @ power


def _localize_set(windows: list[WindowResiduals], noise_variance: float, speed_scale: float) -> dict:
    residual = np.concatenate([np.asarray(w.residual, float) for w in windows])
    squared = residual**2
    excess = squared - noise_variance
    use_excess = excess.sum() > 0
    per_sample = (excess if use_excess else squared).sum(axis=1)
    total = per_sample.sum()
    reversals = reversal_times(windows)
    masks = [regime_masks(w, speed_scale, reversals[w.log_name]) for w in windows]
    stacked = {name: np.concatenate([m[name] for m in masks]) for name in REGIMES}

    signal_totals = np.clip((excess if use_excess else squared).sum(axis=0), 0.0, None)
    signals = dict(zip(("theta", "phi"), _fractions(signal_totals)))

    regimes = []
    for name in REGIMES:
        mask = stacked[name]
        regimes.append(
            {
                "regime": name,
                "share_of_gap": _share(per_sample[mask].sum(), total),
                "share_of_samples": float(mask.mean()),
                "definition": _definition(name, speed_scale),
            }
        )

    bands = [band_power(w, noise_variance if use_excess else 0.0) for w in windows]
    edges = max((e for e, _ in bands), key=len)
    band_totals = np.zeros(len(edges) - 1)
    for e, p in bands:
        band_totals[: len(e) - 1] += p.sum(axis=1)
    frequency_bands = [
        {"low_hz": float(lo), "high_hz": float(hi), "share_of_gap": float(s)}
        for lo, hi, s in zip(edges[:-1], edges[1:], _fractions(np.clip(band_totals, 0.0, None)))
    ]

    return {
        "signals": signals,
        "windows": _worst_windows(windows, masks, bands, noise_variance if use_excess else 0.0, total),
        "regimes": regimes,
        "frequency_bands": frequency_bands,
        "basis": (
            "excess squared residual over the sensor noise"
            if use_excess
            else "squared residual (no excess over the sensor noise)"
        ),
    }


def _worst_windows(windows, masks, bands, noise_variance: float, total: float) -> list[dict]:
    scores = np.array([float((np.asarray(w.residual, float) ** 2 - noise_variance).sum()) for w in windows])
    positive = np.clip(scores, 0.0, None)
    if positive.sum() <= 0:
        return []
    order = np.argsort(-positive, kind="stable")
    chosen, held = [], 0.0
    for index in order[:MAX_WORST]:
        comparable = positive[index] >= WORST_SHARE * positive[order[0]]
        if positive[index] <= 0 or (held >= WORST_SHARE * positive.sum() and not comparable):
            break
        chosen.append(int(index))
        held += positive[index]
    intervals = []  # merged: (log, start, end, [window indices])
    for index in sorted(chosen, key=lambda i: (windows[i].log_name, windows[i].time[0])):
        w = windows[index]
        step = float(np.median(np.diff(w.time))) if len(w.time) > 1 else 0.0
        last = intervals[-1] if intervals else None
        if last is not None and last[0] == w.log_name and w.time[0] <= last[2] + 1.5 * step:
            last[2] = max(last[2], float(w.time[-1]))
            last[3].append(index)
        else:
            intervals.append([w.log_name, float(w.time[0]), float(w.time[-1]), [index]])
    reported = []
    for log_name, start, end, members in intervals:
        reported.append(
            {
                "log": log_name,
                "start": start,
                "end": end,
                "why": _why(windows, masks, bands, members, noise_variance),
                "share_of_gap": _share(float(scores[members].sum()), total),
            }
        )
    reported.sort(key=lambda item: -item["share_of_gap"])
    return reported


def _why(windows, masks, bands, members, noise_variance: float) -> str:
    """A short phrase: the dominant signal, the motion regimes that over-hold the excess, the pose, the band."""
    residual = np.concatenate([np.asarray(windows[i].residual, float) for i in members])
    per_sample = np.clip((residual**2 - noise_variance).sum(axis=1), 0.0, None)
    signal_excess = np.clip((residual**2 - noise_variance).sum(axis=0), 0.0, None)
    theta_share = signal_excess[0] / max(signal_excess.sum(), 1e-300)
    signal = "theta" if theta_share >= 0.65 else "phi" if theta_share <= 0.35 else "theta and phi"
    flags = {name: np.concatenate([masks[i][name] for i in members]) for name in REGIMES}
    weight = max(per_sample.sum(), 1e-300)
    pose = max(_POSES, key=lambda name: per_sample[flags[name]].sum())
    parts = [f"{signal} error"]
    for name in _MOTIONS:  # every motion regime that holds most of the interval's excess, over-represented
        held = per_sample[flags[name]].sum() / weight
        if held >= 0.5 and held >= 1.2 * flags[name].mean():
            parts.append(_PHRASES[name])
    parts.append(_PHRASES[pose])
    edges = max((bands[i][0] for i in members), key=len)
    band_totals = np.zeros(len(edges) - 1)
    for i in members:
        e, p = bands[i]
        band_totals[: len(e) - 1] += p.sum(axis=1)
    shares = _fractions(np.clip(band_totals, 0.0, None))
    top = int(np.argmax(shares))
    if shares[top] >= 0.6:
        parts.append(f"mostly {edges[top]:g}-{edges[top + 1]:g} Hz")
    return ", ".join(parts)


def reversal_times(windows: list[WindowResiduals]) -> dict[str, np.ndarray]:
    """Per log, the sorted times [s] where the predicted phi_dot changes sign, read across the log's windows in
    time order (a reversal between two windows counts for both)."""
    out = {}
    for name in {w.log_name for w in windows}:
        time = np.concatenate([w.time for w in windows if w.log_name == name])
        phi_dot = np.concatenate([w.state[:, 3] for w in windows if w.log_name == name])
        order = np.argsort(time, kind="stable")
        time, sign = time[order], np.sign(phi_dot[order])
        change = np.flatnonzero(sign[1:] * sign[:-1] < 0)
        out[name] = 0.5 * (time[change] + time[change + 1])
    return out


def _near(time: np.ndarray, events: np.ndarray, radius: float) -> np.ndarray:
    """Samples within ``radius`` [s] of any of the sorted ``events``."""
    if events.size == 0:
        return np.zeros(len(time), bool)
    after = np.clip(np.searchsorted(events, time), 0, len(events) - 1)
    before = np.clip(after - 1, 0, len(events) - 1)
    return np.minimum(np.abs(time - events[after]), np.abs(time - events[before])) <= radius


def _definition(name: str, speed_scale: float) -> str:
    return {
        "arm velocity reversal": f"phi_dot changes sign within +-{REVERSAL_WINDOW_S:g} s",
        "near-zero arm speed": f"|phi_dot| < {NEAR_ZERO_FRACTION * speed_scale:.3g} rad/s "
        f"({NEAR_ZERO_FRACTION:g} x its 90th percentile)",
        "high arm speed": f"|phi_dot| > {HIGH_SPEED_FRACTION * speed_scale:.3g} rad/s "
        f"({HIGH_SPEED_FRACTION:g} x its 90th percentile)",
        "upright": f"|theta| < {POSE_RADIUS:g} rad",
        "hanging": f"|theta - pi| < {POSE_RADIUS:g} rad (wrapped)",
        "swinging": "neither upright nor hanging",
        "torque saturation": "|command| >= 0.98 torque_limit",
    }[name]


def _fractions(values: np.ndarray) -> list[float]:
    total = float(np.sum(values))
    if total <= 0:
        return [0.0] * len(values)
    return [float(v) / total for v in values]


def _share(part: float, total: float) -> float:
    return float(np.clip(part / total, 0.0, 1.0)) if total > 0 else 0.0


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + math.pi) % (2 * math.pi) - math.pi
