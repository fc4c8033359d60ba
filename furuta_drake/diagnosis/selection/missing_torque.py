"""The torque the accepted effects still miss (stage 4b of the diagnosis): its form over the term library of
:mod:`~furuta_drake.effects.torque_library`, estimated on the train windows and judged on the held-out ones.

Estimation. At the final model a small generalised torque tau(x) = sum_j c_j T_j(x) changes each window's
predicted angles linearly in its coefficients: the residuals' sensitivity to each term (one batch prediction per
term and joint, the initial states' share projected out as in the fit's Jacobian) makes the residual a linear
regression on the coefficients. Each term is scaled by its RMS along the train windows, so a coefficient is the
term's RMS torque [N m]. The sparse regression is orthogonal matching pursuit (scikit-learn), its number of terms
chosen by cross-validation over the train windows (folds of whole windows). Its strongest new term is added, all
kept terms are fitted again by the fit's nonlinear least squares (variable projection,
:mod:`~furuta_drake.diagnosis.selection.fit`), and the pursuit runs again on the residual there, until cross-validation
wants no further term: a large torque's effect on the angles is not linear, and a term fitted at its own size
leaves no remainder for spare terms to chase. The 95 % intervals come from the fit's block bootstrap over windows.
Thresholded least squares (PySINDy's STLSQ) is no use here: over the arm's range on a balancing run the library's
terms are nearly collinear (sin(k phi) for several k, a rate and its tanh), so the full least squares it thresholds
has huge cancelling coefficients and keeps most of the library at every threshold; a pursuit never fits collinear
terms together unless each earns its place.

Judgement. The torque is kept only when the final model with it passes the rule an effect must pass against the
model holding all the others (:func:`~furuta_drake.diagnosis.selection.rule.is_kept`, bootstrapped over the held-out
windows), so that it never claims what a listed effect explains.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares
from sklearn.linear_model import OrthogonalMatchingPursuit

from furuta_drake.diagnosis.gap.metric import (
    GapResult,
    Windows,
    evaluate_gap,
    fixed_state_residuals_of,
    project_out_states,
    projected_residuals,
)
from furuta_drake.diagnosis.selection.fit import Residuals, bootstrap_samples, interval
from furuta_drake.diagnosis.selection.rule import IMPLAUSIBLE_SCALE, Bootstrap, Comparison, is_kept
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.torque_library import JOINTS, TERMS, closest_effect, expression, term_values
from furuta_drake.effects.vocabulary import CANDIDATES, apply_effects
from furuta_drake.parallel import one_blas_thread

TORQUE_WINDOWS = 200  # train windows the regression uses at the most (evenly drawn, seeded)
FOLDS = 5  # cross-validation folds of whole windows
MAX_TERMS = 6  # terms kept at the most
CV_MARGIN = 0.01  # a further term must lower the cross-validated squared residual by more than one standard error
# plus 1 % of the squared residual without a torque (a near-perfect fit's linearisation leaves a structured
# remainder that spare terms would chase)
STEP = 1e-3  # finite-difference torque of the sensitivities [fraction of m g l]


@dataclass
class MissingTorque:
    """The torque found beyond the accepted effects, judged on the held-out windows."""

    terms: list[tuple[int, int, float]]  # (joint, term index, coefficient [N m])
    intervals: list[tuple[float, float]]  # 95 % interval of each coefficient [N m]
    heldout: GapResult  # the final model with the torque, on the held-out windows
    over_final: Comparison  # against the final model without it
    over_nominal: Comparison  # against the nominal model
    scatter: dict[str, dict] = field(default_factory=dict)  # joint -> per-window estimates for the plot

    @property
    def kept(self) -> bool:
        return bool(self.terms) and is_kept(self.over_final)

    def joint_expression(self, joint: int) -> str:
        return expression([(term, c) for j, term, c in self.terms if j == joint])


def bound_labels(result) -> list[tuple[str, str, str]]:
    """(effect, parameter, "lower" | "upper") of every parameter of a fitted model (a
    :class:`~furuta_drake.diagnosis.selection.fit.FitResult`) fitted at an end of its search range."""
    out = []
    for label in result.at_bounds:
        where, end = label.rsplit(" ", 1)
        name, param = where.split(".", 1)
        out.append((name, param, end.strip("()")))
    return out


def stand_ins(result) -> list[str]:
    """The effects of a fitted model (a :class:`~furuta_drake.diagnosis.selection.fit.FitResult`) that may stand in for
    something outside the vocabulary: a parameter fitted at its search bound where the law is not a simpler one of
    the vocabulary there (:meth:`~furuta_drake.effects.vocabulary.Candidate.nested_law`: presliding at zero is a
    Coulomb law that sticks, no stand-in), or an inertia scale beyond ``IMPLAUSIBLE_SCALE`` either way."""
    bounded = {name for name, param, end in bound_labels(result) if CANDIDATES[name].nested_law(param, end) is None}
    inertia = result.effects.get("inertia_mismatch")
    if inertia is not None and any(not 1 / IMPLAUSIBLE_SCALE < v < IMPLAUSIBLE_SCALE for v in inertia.values):
        bounded.add("inertia_mismatch")
    return [name for name in result.effects if name in bounded]


def bound_notes(result) -> list[str]:
    """One note per parameter of a fitted model at an end of its search range: the simpler law it is there, or
    that the law is stretched to its limit."""
    notes = []
    for name, param, end in bound_labels(result):
        law = CANDIDATES[name].nested_law(param, end)
        notes.append(
            f"{name}.{param} is at the {end} end of its search range: "
            + (f"the law is {law} there" if law else "the law is stretched to its limit (it may stand in for another)")
        )
    return notes


def copies(torque: MissingTorque, name: str) -> bool:
    """Whether the torque on some joint takes the shape of the listed effect ``name`` along the train windows
    (:func:`~furuta_drake.effects.torque_library.closest_effect`)."""
    for joint, scatter in torque.scatter.items():
        if closest_effect(joint, scatter["fitted"], term_values(*scatter["state"])) == name:
            return True
    return False


def term_scales(windows: Windows) -> np.ndarray:
    """Each term's RMS along the windows' (smoothed) initial states."""
    x = np.concatenate(windows.initial_states, axis=1)[:4]
    return np.sqrt(np.mean(term_values(*x) ** 2, axis=1))


def design(model: Model, windows: Windows, counts: int, scales: np.ndarray):
    """The regression's (X, y, groups): per (joint, term) column the residuals' change per N m of the term's RMS
    torque, with the initial states' share projected out; y the residuals' negative; groups each row's window."""
    raw, states, jacobians = projected_residuals(model, windows, counts)
    step = STEP * model.gravity_torque
    joint_terms = [(joint, term, step / scale) for joint in range(len(JOINTS)) for term, scale in enumerate(scales)]
    shifted = [with_terms(model, [joint_term]) for joint_term in joint_terms]
    columns = [
        _rows([project_out_states(m - r, J) / step for m, r, J in zip(moved, raw, jacobians)])
        for moved in fixed_state_residuals_of(shifted, windows, states, counts)
    ]
    groups = _rows(
        [
            np.broadcast_to(np.arange(r.shape[2]) + sum(s.size for s in windows.starts[:i]), r.shape)
            for i, r in enumerate(raw)
        ]
    )
    return np.column_stack(columns), -_rows(raw), groups


def with_terms(model: Model, terms) -> Model:
    """``model`` with the torque ``terms`` (joint, term index, coefficient [N m]) added to its own: a model's
    terms (a rig file's torque, a torque kept earlier) are a fixed base the regression adds to."""
    return model.replace(unmodelled_terms=tuple(model.unmodelled_terms) + tuple(terms))


def _rows(per_log: list[np.ndarray]) -> np.ndarray:
    """Per-log (horizon, 2, W) arrays as one vector, the start row 0 left out, NaN as 0."""
    return np.nan_to_num(np.concatenate([v[1:].ravel() for v in per_log]))


def sparse_coefficients(X: np.ndarray, y: np.ndarray, groups: np.ndarray, seed: int) -> np.ndarray:
    """Orthogonal matching pursuit coefficients of y ~ X with k = 0 .. ``MAX_TERMS`` terms, k chosen by
    ``FOLDS``-fold cross-validation over the groups: the fewest terms whose error is within one standard error of
    the best plus ``CV_MARGIN``. Each fit runs on the square system of its rows' normal equations (the same least
    squares, one row per term)."""
    fold = np.random.default_rng(seed).permutation(np.unique(groups).size)
    fold = fold[np.unique(groups, return_inverse=True)[1]] % FOLDS
    grams = [_normal_equations(X[fold == k], y[fold == k]) for k in range(FOLDS)]
    total = [sum(g[i] for g in grams) for i in range(3)]
    ridge = 1e-9 * float(np.mean(np.diag(total[0]))) * np.eye(X.shape[1])

    def fit(terms, gram):
        if terms == 0:
            return np.zeros(X.shape[1])
        upper = np.linalg.cholesky(gram[0] + ridge).T
        pursuit = OrthogonalMatchingPursuit(n_nonzero_coefs=terms, fit_intercept=False)
        return pursuit.fit(upper, np.linalg.solve(upper.T, gram[1])).coef_

    def error(c, gram):  # the held-out fold's squared residual, relative to that of no torque
        return float(c @ gram[0] @ c - 2.0 * c @ gram[1] + gram[2]) / max(gram[2], 1e-300)

    with one_blas_thread():  # small dense solves
        errors = np.array(
            [[error(fit(k, [a - b for a, b in zip(total, g)]), g) for g in grams] for k in range(MAX_TERMS + 1)]
        )
        mean, se = errors.mean(axis=1), errors.std(axis=1, ddof=1) / np.sqrt(FOLDS)
        best = int(np.argmin(mean))
        return fit(min(k for k in range(MAX_TERMS + 1) if mean[k] <= mean[best] + se[best] + CV_MARGIN), total)


def _normal_equations(X: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    return X.T @ X, X.T @ y, float(y @ y)


def _refit(model: Model, start: list[tuple[int, int, float]], windows: Windows, counts: int, settings):
    """``start``'s terms with their coefficients fitted again beside ``model``'s own terms by the fit's
    variable-projection least squares, and their bootstrap samples (resamples, terms)."""
    keys = [(joint, term) for joint, term, _ in start]
    x0 = np.array([c for _, _, c in start])
    span = np.maximum(4.0 * np.abs(x0), STEP * model.gravity_torque)
    low, high = x0 - span, x0 + span

    def model_at(x):
        return with_terms(model, [(j, t, float(c)) for (j, t), c in zip(keys, x)])

    residuals = Residuals(model_at, windows, counts, high - low, high)
    result = least_squares(
        residuals.cost, x0, jac=residuals.jacobian, bounds=(low, high), x_scale=span / 10, max_nfev=settings.max_nfev
    )
    samples = bootstrap_samples(model_at, result.x, windows, counts, high - low, low, high, settings, None)
    return [(j, t, float(c)) for (j, t), c in zip(keys, result.x)], samples


def find_missing_torque(
    final: Model,
    nominal_heldout: np.ndarray,
    final_heldout: np.ndarray,
    train: Windows,
    heldout: Windows,
    counts: int,
    bootstrap: Bootstrap,
    settings: DiagnosisSettings,
) -> MissingTorque | None:
    """The torque ``final`` misses on the train windows, judged on the held-out ones (module docstring); None
    when the regression keeps no term. Its terms add to ``final``'s own (a rig file's torque stays as stated).
    ``nominal_heldout``, ``final_heldout``: the per-window excess squared residuals of the nominal and the final
    model on ``heldout``; ``bootstrap``: the rule's (:meth:`~furuta_drake.diagnosis.selection.stepwise.Selection.
    rule_bootstrap`), which judges the torque over ``final`` (its reduction over nominal reads the whole gap)."""
    windows = train.subset(TORQUE_WINDOWS, settings.seed)
    scales = term_scales(windows)
    X, y, groups = design(final, windows, counts, scales)
    found, samples, design_at, residual = [], None, X, y
    while len(found) < MAX_TERMS:
        coefficients = sparse_coefficients(design_at, residual, groups, settings.seed)
        kept = {(j, t) for j, t, _ in found}
        new = [i for i in np.flatnonzero(coefficients) if divmod(int(i), len(TERMS)) not in kept]
        if not new:
            break
        joint, term = divmod(int(max(new, key=lambda i: abs(coefficients[i]))), len(TERMS))
        start = [*found, (joint, term, float(coefficients[joint * len(TERMS) + term] / scales[term]))]
        found, samples = _refit(final, start, windows, counts, settings)
        design_at, residual, _ = design(with_terms(final, found), windows, counts, scales)
    if samples is None:
        return None
    gap = evaluate_gap(with_terms(final, found), heldout, counts)
    return MissingTorque(
        found,
        [interval(samples[:, i]) for i in range(samples.shape[1])],
        gap,
        bootstrap.evidence(final_heldout, gap.per_window),
        bootstrap.whole().evidence(nominal_heldout, gap.per_window),
        window_estimates(found, windows, X, y),
    )


def window_estimates(found, windows: Windows, X, y) -> dict[str, dict]:
    """Per joint with a torque: each window's own estimate of a constant torque on that joint [N m] (its residual
    regressed on the constant term's sensitivity), the fitted torque at the window's start, and the state there."""
    states = np.concatenate(windows.initial_states, axis=1)[:4]
    out = {}
    for joint, name in enumerate(JOINTS):
        terms = [(t, c) for j, t, c in found if j == joint]
        if not terms:
            continue
        sensitivity = _per_window(X[:, joint * len(TERMS)], windows)
        residual = _per_window(y, windows)
        estimate = np.sum(sensitivity * residual, axis=0) / np.maximum(np.sum(sensitivity**2, axis=0), 1e-300)
        values = term_values(*states)
        torque = sum(c * values[t] for t, c in terms)
        out[name] = {"state": states, "estimate": estimate, "fitted": torque}
    return out


def _per_window(flat: np.ndarray, windows: Windows) -> np.ndarray:
    """A vector laid out as :func:`_rows` as (rows per window, W) over all logs' windows."""
    parts, offset = [], 0
    for horizon, starts in zip(windows.horizons, windows.starts):
        size = (horizon - 1) * 2 * starts.size
        parts.append(flat[offset : offset + size].reshape(horizon - 1, 2, starts.size).reshape(-1, starts.size))
        offset += size
    return np.concatenate(parts, axis=1) if len({p.shape[0] for p in parts}) == 1 else _ragged(parts)


def _ragged(parts: list[np.ndarray]) -> np.ndarray:
    rows = max(p.shape[0] for p in parts)
    return np.concatenate([np.pad(p, ((0, rows - p.shape[0]), (0, 0))) for p in parts], axis=1)


def beyond_vocabulary(selection, nominal: Model, train, heldout, counts, bootstrap, settings):
    """The torque beyond the effects a selection (:class:`~furuta_drake.diagnosis.selection.stepwise.Selection`) kept,
    or None when none passes the rule; and the notes for the report. An effect that may be a stand-in
    (:func:`stand_ins`) is first replaced by the torque beside the other kept effects when that model passes the
    rule against them, explains the held-out data at least as well as the model holding the stand-in and does not
    take the stand-in's own shape (a torque never displaces a listed effect it copies). A torque that takes the
    shape of a listed effect the rule did not accept is not reported: it holds nothing that effect could not."""
    final, notes = selection.final, []
    if final is None and selection.quiet:
        return None, notes
    judge = selection.rule_bootstrap(bootstrap)

    def beside(result):
        model = apply_effects(nominal, result.effects) if result else nominal
        reference = result.heldout.per_window if result else selection.nominal.per_window
        return find_missing_torque(
            model, selection.nominal.per_window, reference, train, heldout, counts, judge, settings
        )

    notes += bound_notes(final) if final is not None else []
    for name in stand_ins(final) if final is not None else []:
        others = [other for other in selection.accepted if other != name]
        if any(selection.model(others[:k]) is None for k in range(1, len(others) + 1)):
            continue
        trial = beside(selection.model(others) if others else None)
        if trial is not None and trial.kept and trial.heldout.gap <= final.heldout.gap and not copies(trial, name):
            selection.accepted = others
            notes.append(
                f"{name} stood in for a torque outside the vocabulary (fitted at its range's end or at an implausible "
                f"size): the other effects with the unmodelled torque explain the held-out data as well"
            )
            return trial, notes
        notes.append(
            f"{name} may stand in for an effect outside the vocabulary (its range's end or an implausible size)"
        )
    missing = beside(final)
    if missing is None or not missing.kept:
        return None, notes
    listed = [name for name in CANDIDATES if name not in selection.accepted and copies(missing, name)]
    if listed:  # the torque holds only what no listed effect can
        notes.append(
            f"the torque left beside the accepted effects has the shape of {', '.join(listed)}, which the rule did "
            f"not accept beside them: it is not reported as a torque beyond the vocabulary"
        )
        return None, notes
    return missing, notes
