# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The diagnosis stage by stage: the spine to read from top to bottom.

:func:`diagnose` is the entry point; for displacement / velocity inputs without a simulation
its outer loop runs the stages again at a sharper differentiator corner
(:mod:`diagnosis.corner`).  :func:`diagnose_once` runs the stages in order
(``docs/diagnosis.md`` explains what each decides and why):

1. :func:`reference_stage` - the simulation's FRF, a given model, or without either the
   MIMO FIR ``wheel-force fit`` makes on the real data; the residual high-pass;
2. :func:`real_linear_stage` - the one real-data linear fit of the run, ``fit``'s design;
3. :func:`prepare_stage` - pair each output with its source input, then the features and
   the reference's prediction per record (:mod:`diagnosis.features`,
   :mod:`diagnosis.prepared`);
4. :func:`locate_stage` - where each channel's residual lives (:mod:`diagnosis.locate`);
5. :func:`find_stage` - the per-channel selection, then the finders of :data:`FINDERS` in
   order (:mod:`diagnosis.finders`: per channel, agreement across corners, inside the
   structure, structural whole-vehicle comparisons, the pooled kind of hardening), each
   accepting a candidate by one rule (:mod:`finders.acceptance`) and combined by one rule
   (:func:`finders.reconcile.reconcile`: a later finder's finding supersedes what an earlier
   one named of the same effect on its channels); and the motion finder
   (:mod:`finders.motion`), which reads the recordings, not the residual;
6. :func:`rank_stage` - effects seen in the inputs first, then the structural findings, then
   by the squared RMSE removed (:func:`run.ranked`);
7. :func:`choose_stage` - the written model judged on held-out data (the gate half of the
   holdout, or held-out blocks of the training recordings), never worse than the plain fit
   in either figure, and before / real_linear / after scored as ``evaluate`` scores them
   (:mod:`diagnosis.choice`); the motion findings' channels choose between the reference
   and the plain fit;
8. :func:`report_stage` - the motion findings first, one finding per physics
   (:func:`finders.reconcile.merge_motion`), the DESIGN.md result and the summary
   (:mod:`diagnosis.result`, :mod:`diagnosis.text`).
"""
from dataclasses import dataclass
from dataclasses import field
from dataclasses import replace
from typing import Dict, List, Optional, Sequence, Tuple

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.diagnosis import text
from wheel_force_estimator.diagnosis.choice import compare
from wheel_force_estimator.diagnosis.corner import with_sharper_corner
from wheel_force_estimator.diagnosis.features import pairing
from wheel_force_estimator.diagnosis.finders import agreement
from wheel_force_estimator.diagnosis.finders import hardening
from wheel_force_estimator.diagnosis.finders import motion
from wheel_force_estimator.diagnosis.finders import per_channel
from wheel_force_estimator.diagnosis.finders import structural
from wheel_force_estimator.diagnosis.finders import structure
from wheel_force_estimator.diagnosis.finders.reconcile import merge_motion
from wheel_force_estimator.diagnosis.finders.reconcile import reconcile
from wheel_force_estimator.diagnosis.locate import locate_channel
from wheel_force_estimator.diagnosis.prepared import prepare
from wheel_force_estimator.diagnosis.recording import check_compatible
from wheel_force_estimator.diagnosis.recording import MotionRecording
from wheel_force_estimator.diagnosis.result import DiagnosisResult
from wheel_force_estimator.diagnosis.run import DiagnosisConfig
from wheel_force_estimator.diagnosis.run import is_simulation
from wheel_force_estimator.diagnosis.run import ranked
from wheel_force_estimator.diagnosis.run import real_linear_fit
from wheel_force_estimator.diagnosis.run import reference_of
from wheel_force_estimator.diagnosis.selection import pooled_gain

#: The finders of the residual, in the order they run (:func:`find_stage`).  Each sees the
#: findings of those before it; a later one's finding supersedes an earlier one's of the same
#: effect on its channels (:mod:`finders.reconcile`).  Each decides itself in which modes it
#: runs: agreement against a simulation or model, inside the structure without either, the
#: structural comparisons against a simulation's FRF, the pooled hardening against a
#: simulation.
FINDERS = (('per_channel', per_channel), ('agreement', agreement), ('structure', structure),
           ('structural', structural), ('hardening', hardening))


def diagnose(real: Sequence[MotionRecording], sim_or_model=None,
             holdout: Sequence[MotionRecording] = (),
             config: Optional[DiagnosisConfig] = None) -> DiagnosisResult:
    """
    Diagnose what the reference leaves out of the real recordings.

    Without a simulation (none, or a model), for displacement or velocity inputs whose
    differentiator low-pass is left to the default (``fs / 8``), the diagnosis runs a second
    time with the sharper corner of :func:`corner.sharper_lowpass_hz`; the gate half of the
    holdout (without one: the cross-validation blocks) chooses between the two written
    models (mean RMSE over all output channels; a tie keeps the default), and a note in
    ``fit.notes`` says which was kept.

    Parameters
    ----------
    real : sequence of MotionRecording
        Real recordings used to locate and fit (inputs + measured forces).
    sim_or_model : sequence of MotionRecording, FrfModel, reference object or None
        Simulation recordings (the FRF / linear law is fitted on them), a model, or None for
        generic data without a simulation (a linear law is fitted on ``real`` and only
        nonlinear physics are sought).
    holdout : sequence of MotionRecording
        Real recordings NOT used for fitting, for the before/after comparison; when empty
        the comparison uses the held-out blocks of the cross-validation.
    config : DiagnosisConfig, optional
        Features, selection rules and reference settings (defaults when None).

    Returns
    -------
    DiagnosisResult

    Raises
    ------
    DiagnosisError
        Incompatible recordings (rates, channels), too little data to cross-validate, no
        overlap between simulated and real operating ranges.

    """
    config = config or DiagnosisConfig()
    real = tuple(real)
    holdout = tuple(holdout)
    result = diagnose_once(real, sim_or_model, holdout, config)
    # A simulation's linear law for displacement / velocity inputs reads the features itself
    # (F0 + k x + c v + m a): a second corner would change the "before" it is judged against
    # (measured on travel -> Fz: 23.8 -> 78.8 % before, the written model no better).
    if result.model is None or is_simulation(sim_or_model):
        return result

    def once(cfg):
        return diagnose_once(real, sim_or_model, holdout, cfg)
    return with_sharper_corner(result, once, real, holdout, config)


@dataclass
class Run:
    """What the stages hand on to each other within one :func:`diagnose_once`."""

    real: tuple
    holdout: tuple
    config: DiagnosisConfig
    reference: object
    companions: tuple
    mode: str
    sim: tuple
    channels: tuple = ()
    sources: tuple = ()
    partners: tuple = ()
    prep: object = None
    sim_prep: object = None
    real_linear: object = None
    outcomes: Dict[str, object] = field(default_factory=dict)
    notes: List[str] = field(default_factory=list)
    gains: Dict[tuple, float] = field(default_factory=dict)

    @property
    def hp(self) -> float:
        """High-pass of the residual analysis [Hz] (0 = none)."""
        return self.config.selection.highpass_hz

    def prepare(self, sources=None) -> None:
        """Pair each output with its source input (``sources`` when given); features, preds."""
        rec0 = self.real[0]
        if sources is None:
            self.sources, self.partners = pairing(self.channels, rec0.input_channels, self.real)
        else:
            self.sources = sources
        args = (self.reference, self.sources, self.partners, self.config)
        self.prep = prepare(self.real, *args)
        self.sim_prep = prepare(self.sim, *args) if self.sim else None
        self.gains.clear()

    def pooled(self, group, key) -> float:
        """Return the shared-parameter gain of ``key`` over ``group`` (cached)."""
        # Shared-parameter fits are the costly part, and omissions, hardening and ranking
        # ask for the same ones (a group's gain does not depend on its channel order).
        index = (tuple(sorted(group)), key)
        if index not in self.gains:
            self.gains[index] = pooled_gain(self.prep, self.sim_prep, self.channels,
                                            index[0], key, self.config)
        return self.gains[index]


def diagnose_once(real, sim_or_model, holdout, config) -> DiagnosisResult:
    """Run one diagnosis with fixed feature corners: the stages in order (module notes)."""
    run = reference_stage(real, sim_or_model, holdout, config)
    real_linear_stage(run)
    prepare_stage(run)
    mismatch = locate_stage(run)
    found = find_stage(run)
    findings = rank_stage(run, found)
    findings, fit, model = choose_stage(run, findings, found.motion)
    return report_stage(run, mismatch, findings, found.motion, fit, model)


def reference_stage(real, sim_or_model, holdout, config) -> Run:
    """
    Check the recordings, build the reference and set the residual high-pass.

    The residual is high-passed at 1 Hz for an FRF reference of accelerations (the paper's
    figure), left unfiltered otherwise, unless ``config.residual_highpass_hz`` says.
    """
    check_compatible(real, 'real')
    if holdout:
        check_compatible(real + holdout, 'real and holdout')
    reference, companions, mode, sim = reference_of(real, sim_or_model, config)
    rec0 = real[0]
    hp = config.residual_highpass_hz
    if hp is None:
        hp = 1.0 if reference.kind == 'frf' and rec0.input_quantity == 'acceleration' else 0.0
    config = replace(config, selection=replace(config.selection, highpass_hz=hp))
    return Run(real, holdout, config, reference, companions, mode, sim,
               channels=rec0.output_channels)


def real_linear_stage(run: Run) -> None:
    """
    Fit the one real-data linear model of the run (``fit``'s design on all training data).

    Without a simulation or model it is the reference itself.  Records it cannot fit leave
    it None and a note says why.
    """
    if run.mode == 'linear':
        run.real_linear = run.reference
        return
    try:
        run.real_linear = real_linear_fit(run.real, run.config)
    except DiagnosisError as err:
        run.notes.append(f'no real-data linear model: {err}')


def prepare_stage(run: Run) -> None:
    """Pair each output with its source input; features and reference predictions."""
    run.prepare()


def locate_stage(run: Run) -> list:
    """Return per channel where the residual lives, worst channel first (informative)."""
    prep = run.prep
    located = (locate_channel(ch, [t[o] for t in prep.targets],
                              [p[o] for p in prep.predictions],
                              [c[o] for c in prep.contexts], prep.starts_s,
                              run.real[0].fs_hz, run.hp) for o, ch in enumerate(run.channels))
    return sorted(located, key=lambda m: -m.rmse_pct)


@dataclass(frozen=True)
class Found:
    """What the finders found: the combined findings, each finder's own, the motion ones."""

    findings: Tuple
    by_finder: Dict[str, Tuple]
    motion: Tuple


def find_stage(run: Run) -> Found:
    """
    Run the per-channel selection, then every finder of :data:`FINDERS` in order.

    The selection (:func:`finders.per_channel.select`) fills ``run.outcomes``, which the
    agreement and the search inside the structure read too.  Each finder's findings are
    combined with those before by the one rule of :func:`finders.reconcile.reconcile`.  The
    motion finder reads the recordings only; its findings join at the report.
    """
    per_channel.select(run)
    findings, by_finder = [], {}
    for name, finder in FINDERS:
        by_finder[name] = tuple(finder.find(run, tuple(findings)))
        findings = reconcile(findings, by_finder[name])
    return Found(tuple(findings), by_finder, tuple(motion.find(run, ())))


def rank_stage(run: Run, found: Found) -> list:
    """Return the findings ranked (:func:`run.ranked`)."""
    structural_ids = [id(f) for f in found.by_finder['structural']]
    return ranked(list(found.findings), run.prep, run.channels, run.hp, run.real[0].fs_hz,
                  structural_ids, run.pooled)


def choose_stage(run: Run, findings, motion_found):
    """
    Return ``(findings, FitComparison, written model or None)``.

    Motion findings (clip, tyre in the air) carry no terms, but the real motion differs
    from the simulated one: where they are, the written model is chosen between the
    reference and the plain fit on the real data (no longer "no change").
    """
    lin = run.real_linear
    frf_sim = run.mode == 'sim' and run.reference.kind == 'frf'
    return compare(
        findings, run.real, run.reference, run.mode, run.holdout, run.channels, run.sources,
        run.partners, run.config,
        lin.refit if lin is not None else (lambda recs: real_linear_fit(recs, run.config).model),
        lin.model if lin is not None else None,
        motion_channels=sorted({c for m in motion_found for c in m.channels}),
        notes=run.notes, sim=run.sim, sim_fit=run.reference.refit if frf_sim else None)


def report_stage(run: Run, mismatch, findings, motion_found, fit,
                 model) -> DiagnosisResult:
    """
    Return the result: findings, figures, the rejected candidates and the summary.

    The motion findings come first, one per physics (:func:`finders.reconcile.merge_motion`).
    """
    findings = merge_motion(findings, motion_found)
    named = {(c, f.physics) for f in findings for c in f.channels}
    outcomes = run.outcomes
    rejected = tuple(text.rejection(ch, outcomes[ch].rejected) for ch in run.channels
                     if outcomes[ch].rejected is not None and outcomes[ch].rejected[0].gain > 0
                     and (ch, outcomes[ch].rejected[0].hypothesis.physics) not in named)
    rejected = tuple(fit.gated) + rejected
    summary = text.summary(findings, fit, rejected)
    reference = run.reference
    return DiagnosisResult(tuple(mismatch), tuple(findings), fit, tuple(summary),
                           f'{reference.name} ({reference.kind})', rejected, model, reference,
                           getattr(run.real_linear, 'fitted', None))
