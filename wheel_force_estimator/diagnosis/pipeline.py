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
5. :func:`find_stage` - per-channel candidates accepted by one rule against a
   time-shifted-feature null (:mod:`diagnosis.selection`), shared parameters per axis,
   physics inside a structure (:mod:`diagnosis.dynamic`) and the whole-vehicle comparisons
   (:mod:`diagnosis.coupling`, :mod:`diagnosis.omissions`);
6. :func:`rank_stage` - effects seen in the inputs first, then by the squared RMSE removed;
7. :func:`choose_stage` - the motion findings (:mod:`diagnosis.motion`), the written model
   judged on held-out data (the gate half of the holdout, or held-out blocks of the training
   recordings), never worse than the plain fit in either figure, and before / real_linear /
   after scored as ``evaluate`` scores them (:mod:`diagnosis.choice`);
8. :func:`report_stage` - the DESIGN.md result and the summary (:mod:`diagnosis.result`,
   :mod:`diagnosis.text`).
"""
from dataclasses import dataclass
from dataclasses import field
from dataclasses import replace
from typing import Dict, List, Optional, Sequence

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.diagnosis import text
from wheel_force_estimator.diagnosis.agreement import agreed_findings
from wheel_force_estimator.diagnosis.candidates import HYPOTHESES
from wheel_force_estimator.diagnosis.choice import compare
from wheel_force_estimator.diagnosis.corner import with_sharper_corner
from wheel_force_estimator.diagnosis.dynamic import dynamic_findings
from wheel_force_estimator.diagnosis.features import paired_by_coherence
from wheel_force_estimator.diagnosis.features import pairing
from wheel_force_estimator.diagnosis.hardening import add_omissions
from wheel_force_estimator.diagnosis.hardening import pooled_gain
from wheel_force_estimator.diagnosis.hardening import settle_hardening
from wheel_force_estimator.diagnosis.locate import locate_channel
from wheel_force_estimator.diagnosis.motion import merge_motion
from wheel_force_estimator.diagnosis.motion import motion_findings
from wheel_force_estimator.diagnosis.prepared import pieces
from wheel_force_estimator.diagnosis.prepared import prepare
from wheel_force_estimator.diagnosis.recording import check_compatible
from wheel_force_estimator.diagnosis.recording import MotionRecording
from wheel_force_estimator.diagnosis.result import DiagnosisResult
from wheel_force_estimator.diagnosis.run import Builder
from wheel_force_estimator.diagnosis.run import coupling_finding
from wheel_force_estimator.diagnosis.run import DiagnosisConfig
from wheel_force_estimator.diagnosis.run import is_simulation
from wheel_force_estimator.diagnosis.run import ranked
from wheel_force_estimator.diagnosis.run import real_linear_fit
from wheel_force_estimator.diagnosis.run import reference_of
from wheel_force_estimator.diagnosis.run import without_duplicates
from wheel_force_estimator.diagnosis.selection import Selector
from wheel_force_estimator.diagnosis.sources import sources_by_selection


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
    findings, structural = find_stage(run)
    findings = rank_stage(run, findings, structural)
    findings, fit, model = choose_stage(run, findings)
    return report_stage(run, mismatch, findings, fit, model)


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


def prepare_stage(run: Run, sources=None) -> None:
    """Pair each output with its source input; features and reference predictions."""
    rec0 = run.real[0]
    if sources is None:
        run.sources, run.partners = pairing(run.channels, rec0.input_channels, run.real)
    else:
        run.sources = sources
    args = (run.reference, run.sources, run.partners, run.config)
    run.prep = prepare(run.real, *args)
    run.sim_prep = prepare(run.sim, *args) if run.sim else None
    run.gains.clear()


def locate_stage(run: Run) -> list:
    """Return per channel where the residual lives, worst channel first (informative)."""
    prep = run.prep
    located = (locate_channel(ch, [t[o] for t in prep.targets],
                              [p[o] for p in prep.predictions],
                              [c[o] for c in prep.contexts], prep.starts_s,
                              run.real[0].fs_hz, run.hp) for o, ch in enumerate(run.channels))
    return sorted(located, key=lambda m: -m.rmse_pct)


def _candidates(run: Run) -> list:
    """Return the candidates the selection tries."""
    skip_names = {h.physics for h in run.companions}
    # Without --sim/--model the reference is the MIMO FIR fitted on these very records: a
    # delay, a rate or a left-right coupling of the motion lies in its span, so what such a
    # candidate "explains" is the FIR's estimation error (measured: a delay explained 51 % of
    # a linear sine rig's residual), not missing physics.
    return [h for h in HYPOTHESES if h.physics not in skip_names
            and not (run.mode == 'linear' and h.lti)]


def _select_channels(run: Run, candidates) -> None:
    """Run the per-channel selection; with coherence pairing, choose the sources by it."""
    for o, ch in enumerate(run.channels):
        sim_pieces = pieces(run.sim_prep, o, ch) if run.sim_prep else None
        run.outcomes[ch] = Selector(pieces(run.prep, o, ch), run.config.selection,
                                    run.companions, sim_pieces).run(candidates)
    if paired_by_coherence(run.channels, run.real[0].input_channels):
        chosen = sources_by_selection(run.prep, run.sim_prep, run.reference, run.sources,
                                      run.outcomes, run.config, run.companions, candidates)
        if chosen != run.sources:
            prepare_stage(run, chosen)


def find_stage(run: Run):
    """
    Return ``(findings, ids of the structural ones)``: every finder's accepted findings.

    Per channel and shared per axis (:class:`run.Builder`), inside the structure without a
    reference model, agreement across corners against one, and against a simulation the
    whole-vehicle comparisons and the settling of the hardening kind.
    """
    _select_channels(run, _candidates(run))
    config = run.config
    builder = Builder(run.prep, run.outcomes, run.channels, run.sources, run.partners,
                      config, run.companions, run.sim_prep)
    findings = builder.findings()
    if run.mode == 'linear':
        findings += dynamic_findings(run.prep, run.reference, run.channels, run.sources,
                                     run.outcomes, config)
    else:
        findings += agreed_findings(run.outcomes, run.channels, run.prep, run.sim_prep,
                                    builder, config, config.agreement)
    structural = []
    if run.mode == 'sim' and run.reference.kind == 'frf':
        coupling = coupling_finding(run.real, run.reference, run.channels, config, run.hp)
        added = [coupling] if coupling is not None else []
        findings, omitted = add_omissions(findings, run.real, run.sim, run.reference,
                                          run.channels, run.sources, config, run.pooled)
        added += omitted
        findings = without_duplicates(findings, added) + added
        structural = [id(f) for f in added]
    if run.mode == 'sim':
        findings = settle_hardening(findings, builder, run.prep, run.sim_prep, run.channels,
                                    config, run.pooled)
    return findings, structural


def rank_stage(run: Run, findings, structural) -> list:
    """Return the findings ranked (:func:`run.ranked`)."""
    return ranked(findings, run.prep, run.channels, run.hp, run.real[0].fs_hz, structural,
                  run.pooled)


def choose_stage(run: Run, findings):
    """
    Return ``(findings, FitComparison, written model or None)``.

    Motion findings (clip, tyre in the air) carry no terms, but the real motion differs
    from the simulated one: where they are, the written model is chosen between the
    reference and the plain fit on the real data (no longer "no change").
    """
    motion = motion_findings(run.real, run.sim, run.sources, run.config.motion)
    lin = run.real_linear
    frf_sim = run.mode == 'sim' and run.reference.kind == 'frf'
    findings, fit, model = compare(
        findings, run.real, run.reference, run.mode, run.holdout, run.channels, run.sources,
        run.partners, run.config,
        lin.refit if lin is not None else (lambda recs: real_linear_fit(recs, run.config).model),
        lin.model if lin is not None else None,
        motion_channels=sorted({c for m in motion for c in m.channels}), notes=run.notes,
        sim=run.sim, sim_fit=run.reference.refit if frf_sim else None)
    return merge_motion(findings, motion), fit, model


def report_stage(run: Run, mismatch, findings, fit, model) -> DiagnosisResult:
    """Return the result: findings, figures, the rejected candidates and the summary."""
    named = {(c, f.physics) for f in findings for c in f.channels}
    outcomes = run.outcomes
    rejected = tuple(text.rejection(ch, outcomes[ch].rejected) for ch in run.channels
                     if outcomes[ch].rejected is not None and outcomes[ch].rejected[0].gain > 0
                     and (ch, outcomes[ch].rejected[0].hypothesis.physics) not in named)
    rejected = tuple(fit.gated) + rejected
    summary = text.summary(findings, fit, rejected)
    reference = run.reference
    return DiagnosisResult(tuple(mismatch), tuple(findings), fit, tuple(summary),
                           f'{reference.name} ({reference.kind})', rejected, model, reference)
