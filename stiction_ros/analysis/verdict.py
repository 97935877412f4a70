"""
The combined verdict: is the valve sticking, with a score from 0 to 1.

With a measured valve position the answer comes from the fits: the valve
sticks when the identified S is clearly above zero (its 95 % range starts
above ``MIN_S``), the stiction model explains the MV much better than an
ideal valve does, and the fit needs a slip jump (J's 95 % range starts at
``MIN_J`` or above, and at OP's move in one sample while the valve moves:
play taken up between two samples shows as a jump that size, ``j_floor``).
A band without a jump is the chapter's pure deadband
(J = 0): play, from a worn linkage or a positioner's deadband as much as
from friction, which moves the valve smoothly once taken up.  It is answered
``no stiction`` with the play's size, as ``--explain`` and the learned
detector answer it (issue 18 counts deadband and backlash as look-alikes), and
``cannot tell`` where J's range straddles ``MIN_J``.  No model removes a
reading's noise, so a fit may instead remove ``MIN_IMPROVEMENT`` of what an
ideal valve leaves above MV's noise (:mod:`.noise_share`); one that removes
neither, only because the noise is most of that MSE (the fit's MSE within
``NOISE_FIT`` times the noise variance), is ``cannot tell``.  So is a fit
whose valve starts to move fewer than ``MIN_SLIPS`` times: a constant that
beats an ideal valve identifies no band or jump.

A real reading differs from OP first through its timing and instruments, so
a claim must also beat the best valve without friction (dead time, lag,
calibration), and ``no stiction`` must be explained by one.  A reading late
or off in offset and gain can also hide a sticking valve from the plain fits
(a dead time makes stick-slip look like play): where they show no stiction,
stick-slip refitted behind that valve's dead time and calibration answers
``stiction`` when it clears the same floors, removes ``MIN_IMPROVEMENT`` of
that valve's MSE (or of what it leaves above MV's noise) and fits better
than the plain fit, play included; so a claim of none that rests on that
valve must beat this refit too.  The
plain fits' claim and an answer of none that rests on that valve count what
lies above MV's noise as well: where the two tie above it, ``cannot tell``;
where stick-slip itself fits within the noise estimate's error of the noise,
a valve without friction that fits as well is the answer, as before.
Where that valve needs a calibration no working reading has, it explains no
stiction away, but a claim must still fit MV better (``reading_fault``).  An
answer of none that rests on no such valve needs MV's noise known (a held
reading reads none, fast moves too much: ``noise_unknown``), and play must
fit MV within ``NOISE_FIT`` times that noise.

Without them the OP/PV signatures vote (:mod:`.signature_vote`).
"""

from dataclasses import dataclass

from stiction_ros.analysis.frictionless_valve import chain_words, plausible
from stiction_ros.analysis.measures.still import SetPointTest, Still
from stiction_ros.analysis.noise_share import below_noise, share_above_noise
from stiction_ros.analysis.signature_vote import from_signatures
from stiction_ros.analysis.signatures.ellipse import no_ellipse

MIN_S = 0.2
MIN_IMPROVEMENT = 0.5
# A slip jump (% of span) below this is none; --explain claims stick-slip from the same floor.
MIN_J = 0.05
# A fit whose MSE is within this factor of MV's own noise variance leaves only noise.
NOISE_FIT = 1.5
# A band and jump need repeated slips to be told from a one-off move: one cycle is two.
MIN_SLIPS = 3


@dataclass(frozen=True)
class FitVerdict:
    """
    What the valve fits say about a measured valve position.

    Attributes
    ----------
    detected : bool or None
        True for stiction, False for none, None for ``cannot tell``.
    score : float
        The share of an ideal valve's MSE the best fit removes (0-1); behind
        the reading's timing, the share of the valve without friction's MSE
        the refit removes; where the share of what that valve leaves above
        MV's noise decided instead, that share (at most 1); 0 where the
        answer rests on no stick-slip.
    size : float
        The best fit's S (% of span), the refit's behind the reading's timing.
    reason : str
        The sentence the report prints.
    play : float or None
        The S of a band without a slip jump, else None.
    code : str or None
        Why the answer is ``cannot tell`` (``noisy_mv``,
        ``slip_unresolved``, ``few_slips``, ``frictionless_fits``, ``unexplained_mv``,
        ``reading_fault``, ``noise_unknown``), else None.
    without_friction : str or None
        The stages of the valve without friction that explains MV where the
        answer rests on it (``no stiction``), else None.
    read_behind : str or None
        The dead time and calibration stick-slip was read through where the
        answer rests on that refit (``stiction``), else None.

    """

    detected: bool | None
    score: float
    size: float
    reason: str
    play: float | None = None
    code: str | None = None
    without_friction: str | None = None
    read_behind: str | None = None


def from_fits(fits: list[dict]) -> FitVerdict:
    """
    Return what the fits say about stiction, from the fit of least MSE.

    Parameters
    ----------
    fits : list of dict
        Each model's fit as the report writes it: ``model``, ``S``, ``J``,
        ``mse`` and, where known, ``S_interval``, ``J_interval``,
        ``improvement``, ``mv_noise_var``, ``frictionless`` (the best valve
        without friction), ``calibrated_mse`` and ``behind`` (stick-slip
        refitted behind that valve's dead time and calibration,
        :mod:`stiction_ros.analysis.stick_slip_behind`).

    Notes
    -----
    Where the plain fits do not show stiction, stick-slip read behind the
    reading's dead time and calibration shows it when its band and jump are
    clear by the same floors, it removes at least ``MIN_IMPROVEMENT`` of the
    frictionless valve's MSE with a calibration a working reading has, and it
    fits MV better than the plain fit does.

    """
    told = _plain(fits)
    best = min(fits, key=lambda f: f['mse'])
    behind, chain = best.get('behind'), best.get('frictionless')
    if told.detected is not True and behind and chain and shows_behind(behind, best):
        return _read_behind(behind, chain, best)
    return told


def behind_bar(best: dict) -> tuple[float, float]:
    """
    Return the MSEs a refit behind the reading's timing must reach and beat.

    At most half of the frictionless valve's (``best['frictionless']``), or
    of what it leaves above MV's noise (:mod:`.noise_share`), and under the
    plain fit's own (calibrated where that helps): play read on time that
    fits better is play, whatever a slip behind a dead time makes of it.
    ``best``: the plain fit of least MSE, as the report writes it.
    """
    F, noise = best['frictionless']['mse'], best.get('mv_noise_var')
    reach = (1.0 - MIN_IMPROVEMENT) * F
    # A fit down to the noise has a share (1) only where F's excess over it is clear.
    if noise and share_above_noise(noise, F, noise, best.get('samples')) is not None:
        reach = max(reach, F - MIN_IMPROVEMENT * (F - noise))
    return reach, _stick_slip_mse(best)


def shows_behind(behind: dict, best: dict) -> bool:
    """Return whether stick-slip behind the reading's timing shows friction (``from_fits``)."""
    if not behind.get('S_interval') or not behind.get('J_interval'):
        # Not computed where the refit fit too poorly to claim anything.
        return False
    reach, under = behind_bar(best)
    s_lo, j_lo = behind['S_interval'][0], behind['J_interval'][0]
    return bool(s_lo >= MIN_S and j_lo >= j_floor(best) and behind['plausible']
                and behind.get('slips', MIN_SLIPS) >= MIN_SLIPS
                and behind['mse'] <= reach and behind['mse'] < under)


def _read_behind(behind: dict, chain: dict, best: dict) -> FitVerdict:
    F, K, noise = chain['mse'], behind['mse'], best.get('mv_noise_var')
    share = 1.0 - K / F if F > 0 else 0.0
    above = share_above_noise(K, F, noise, best.get('samples'))
    noisy = ('' if above is None or share >= MIN_IMPROVEMENT else
             f" and {min(100.0, 100.0 * above):.0f} % of what it leaves above MV's noise "
             f'({noise:.4g})')
    si, ji = behind['S_interval'], behind['J_interval']
    late = (f'dead time {behind["dead_time_s"]:.3g} s, ' if behind['dead_time_s'] > 0.0
            else '')
    stages = f'{late}MV = {behind["offset"]:.2f} + {behind["gain"]:.3f} x position'
    evidence = share if not noisy else max(share, above or 0.0)
    return FitVerdict(True, max(0.0, min(1.0, evidence)), behind['S'], (
        f'{behind["model"]} read through the timing and calibration of the position reading '
        f'({stages}) fits MV with '
        f'S = {behind["S"]:.2f} % (95 % range {si[0]:.2f}-{si[1]:.2f}), J = '
        f'{behind["J"]:.2f} % (95 % range {ji[0]:.2f}-{ji[1]:.2f}), MSE {K:.4g}, '
        f'{100 * share:.0f} % below the best valve without friction ({chain_words(chain)}, '
        f'MSE {F:.4g}){noisy}: a sticking valve whose slips the plain fits, reading MV as on '
        'time and calibrated, could not resolve'), read_behind=stages)


def _plain(fits: list[dict]) -> FitVerdict:
    best = min(fits, key=lambda f: f['mse'])
    improvement = best.get('improvement')
    interval = best.get('S_interval')
    lo = interval[0] if interval else best['S']
    jumps = best.get('J_interval')
    j_lo, j_hi = (jumps[0], jumps[1]) if jumps else (best['J'], best['J'])
    floor = j_floor(best)
    score = 0.0 if improvement is None else max(0.0, min(1.0, improvement))
    noise = best.get('mv_noise_var')
    above = share_above_noise(best['mse'], best.get('ideal_valve_mse'), noise,
                              best.get('samples'))
    banded = bool(lo >= MIN_S and (improvement is None or improvement >= MIN_IMPROVEMENT
                                   or (above is not None and above >= MIN_IMPROVEMENT)))
    if banded and improvement is not None and improvement < MIN_IMPROVEMENT:
        # The share above the noise decided: it is the evidence, not the plain share.
        score = min(1.0, above or 0.0)
    detected = banded and j_lo >= floor
    ranged = f' (95 % range {interval[0]:.2f}-{interval[1]:.2f})' if interval else ''
    j_ranged = f' (95 % range {jumps[0]:.2f}-{jumps[1]:.2f})' if jumps else ''
    why = (f'{best["model"]} fits the measured MV with S = {best["S"]:.2f} %{ranged}, '
           f'J = {best["J"]:.2f} %, MSE {best["mse"]:.4g}')
    if improvement is not None:
        why += f', {100 * improvement:.0f} % below the MSE of an ideal valve'
        if above is not None and improvement < MIN_IMPROVEMENT:
            why += f' ({100 * above:.0f} % of what it leaves above the noise)'
    if (not banded and lo >= MIN_S and j_lo >= floor and improvement is not None
            and noise and best['mse'] <= NOISE_FIT * noise):
        # Stick-slip that fits down to the reading's noise, where the noise is most of
        # what an ideal valve misses too: the share it removes says nothing then.
        return FitVerdict(None, 0.0, best['S'], (
            f'stick-slip (S = {best["S"]:.2f} %{ranged}, J = {best["J"]:.2f} %{j_ranged}) '
            f'fits MV down to its noise (MSE {best["mse"]:.4g}, against {noise:.4g} from its '
            'sample-to-sample changes), but that noise is most of what an ideal valve '
            f'misses too, so the fit removes only {100 * improvement:.0f} % of its MSE '
            f'(under {100 * MIN_IMPROVEMENT:.0f} %): stick-slip under a noisy reading, or a '
            'lag, dead time or calibration the plain models leave out; --explain tests '
            f'friction against a valve without it, held out; {why}'), code='noisy_mv')
    chain = best.get('frictionless')
    if detected and chain and plausible(chain) and not _beats(best, chain, noise):
        return _without_friction(best, chain, noise, why)
    if detected and chain and not plausible(chain) and chain['mse'] < _stick_slip_mse(best):
        # That valve needs a calibration no working reading has (one imitating friction
        # comes close), yet fits better: a positioner fault, or a characteristic.
        return FitVerdict(None, 0.0, best['S'], (
            f'a valve without friction fits MV better than stick-slip ({_k_words(best)}), '
            f'with MSE {chain["mse"]:.4g}, but only with a calibration no working reading '
            f'has ({chain_words(chain)}): a positioner fault, or a nonlinear characteristic '
            f'between the stem and its reading, which friction does not explain; {why}'),
            code='reading_fault')
    if not banded and chain and not explains(chain, noise):
        # No stiction is a claim too: that a valve without friction explains MV.
        return _unexplained(best, chain, noise, lo >= MIN_S and j_lo >= floor, why)
    if (not banded and chain and lo >= MIN_S and j_lo >= floor
            and _stick_slip_mse(best) < chain['mse']):
        # ... and at least as well as stick-slip with a clear band and jump does.
        return _alike(best, chain, why)
    if chain and (not banded or (not detected and explains(chain, noise)
                                 and chain['mse'] <= _stick_slip_mse(best))):
        # Play, or a slip jump too small to tell, fitted worse than a valve without
        # friction fits MV down to its noise: that valve is the answer.
        stages = chain_words(chain)
        beside = ('at least as well as stick-slip' if chain['mse'] <= _stick_slip_mse(best)
                  else f'stick-slip, without a clear band and slip jump, leaving '
                       f'{_k_words(best)}')
        return FitVerdict(False, 0.0 if banded else score, best['S'], (
            f'{why}; a valve without friction ({stages}) explains MV down to its noise '
            f'(MSE {chain["mse"]:.4g}, against {noise:.4g} from its sample-to-sample '
            f'changes; {beside})'), without_friction=stages)
    if banded and best.get('slips', MIN_SLIPS) < MIN_SLIPS:
        # Play is a band too: a valve that barely moves identifies neither.
        return FitVerdict(None, 0.0, best['S'], (
            f"the fitted valve starts to move {best['slips']} times in the record: a "
            'constant (or a move or two) fits MV better than an ideal valve, for a reading '
            'off in offset, clipped at a stop or drifting, and its band and slip jump are '
            f'not identified, however narrow their ranges; {why}'), code='few_slips')
    if not banded and lo >= MIN_S and j_hi >= MIN_J and noise is not None and (
            not noise or below_noise(
            best['mse'], best.get('ideal_valve_mse'), noise, best.get('samples'))):
        # A clear band removing too little of an ideal valve's MSE says no stiction only
        # where the rest is MV's noise, which a held reading or fast moves leave unknown.
        heard = ('most of its sample-to-sample changes are none (a held or quantised '
                 'reading)' if not noise else f'the fit comes under the {noise:.4g} its '
                 'sample-to-sample changes show (MV moves between samples)')
        return FitVerdict(None, 0.0, best['S'], (
            f"a band of {best['S']:.2f} %{ranged} removes under "
            f"{100 * MIN_IMPROVEMENT:.0f} % of an ideal valve's MSE, but MV's noise is not "
            f'known ({heard}), so whether the rest is noise or friction cannot be told; '
            f'{why}'), code='noise_unknown')
    if not banded or detected:
        return FitVerdict(detected, score, best['S'], why)
    # The band is real; the score is the evidence for stick-slip, which it lacks.
    if j_hi < MIN_J and noise is not None and best['mse'] > NOISE_FIT * noise:
        # Play is no stiction only where it explains MV: a lag smooths slips into play.
        left = (f"leaves {best['mse'] / noise:.3g} times MV's noise variance ({noise:.4g})"
                if noise else "MV's noise is not known (most of its changes are none)")
        return FitVerdict(None, 0.0, best['S'], (
            f'play of {best["S"]:.2f} % without a slip jump fits MV best, but it {left}: '
            'a lag in the reading smooths slips into play; --explain fits friction behind '
            f'it; {why}'), code='unexplained_mv' if noise else 'noise_unknown')
    if j_hi < MIN_J:
        return FitVerdict(False, 0.0, best['S'], (
            f'play of {best["S"]:.2f} % without a slip jump: J = {best["J"]:.2f} %{j_ranged} '
            f'is under {MIN_J:g} %, so once OP has taken up the play the valve moves '
            'smoothly (a deadband or backlash: a worn linkage, a positioner deadband, or '
            f'friction whose static and kinetic forces are equal), not stick-slip; {why}'
        ), play=best['S'])
    sampled = ('' if floor <= MIN_J else
               ", OP's move in one sample while the valve moves: play taken up between two "
               'samples shows as a jump that size')
    return FitVerdict(None, 0.0, best['S'], (
        f'a band of {best["S"]:.2f} % whose slip jump cannot be told from none: J = '
        f'{best["J"]:.2f} %{j_ranged} reaches below {floor:.3g} %{sampled}, so stick-slip '
        f'and play without it (a deadband or backlash) fit alike; {why}'),
        code='slip_unresolved')


def j_floor(fit: dict) -> float:
    """
    Return the smallest slip jump a fit resolves (%): ``MIN_J``, or more at coarse sampling.

    A valve breaks away between two samples, so play taken up between them
    shows at the next sample as a jump of up to OP's move in that sample:
    ``fit['op_step']``, OP's median move in one sample while the fitted
    valve moves (``caution.step_while_moving``), where the pipeline gave it.
    """
    return max(MIN_J, fit.get('op_step') or 0.0)


def explains(chain: dict, noise: float | None) -> bool:
    """Return whether a valve without friction explains MV: plausible, fitting to its noise."""
    return bool(noise and plausible(chain) and chain['mse'] <= NOISE_FIT * noise)


def _unexplained(best: dict, chain: dict, noise: float | None, banded_jump: bool,
                 why: str) -> FitVerdict:
    F, stages = chain['mse'], chain_words(chain)
    heard = (f'{noise:.4g} from its sample-to-sample changes' if noise else
             "MV's noise unknown: most of its changes are none, a held or quantised reading")
    if not plausible(chain):
        without = (f'a valve without friction fits only with a calibration no working '
                   f'reading has ({stages}, MSE {F:.4g})')
    else:
        without = f'a valve without friction ({stages}) leaves MSE {F:.4g}'
    if noise and banded_jump and _stick_slip_mse(best) <= NOISE_FIT * noise:
        what = (f'stick-slip fits MV down to its noise ({_k_words(best)}, against {heard}) '
                f'and {without}, yet stick-slip removes under '
                f"{100 * MIN_IMPROVEMENT:.0f} % of an ideal valve's MSE")
    else:
        what = (f'no valve without friction explains MV down to its noise ({heard}, '
                f'{NOISE_FIT:g} times that allowed): {without}; stick-slip leaves '
                f'{_k_words(best)}' + ('' if banded_jump else
                                       ', without a clear band and slip jump'))
    return FitVerdict(None, 0.0, best['S'], (
        f'{what}; friction behind a dead time or calibration the plain models leave out, '
        f'or an effect neither has; --explain fits them together; {why}'),
        code='unexplained_mv')


def _beats(best: dict, chain: dict, noise: float | None) -> bool:
    # Stick-slip removes MIN_IMPROVEMENT of the frictionless valve's MSE, or of its part
    # above MV's noise.
    K, F = _stick_slip_mse(best), chain['mse']
    above = share_above_noise(K, F, noise, best.get('samples'))
    return K <= (1.0 - MIN_IMPROVEMENT) * F or (above is not None and above >= MIN_IMPROVEMENT)


def _stick_slip_mse(fit: dict) -> float:
    """Return the fit's MSE, or less where a calibration (offset, gain) on its MV helps."""
    return min(fit['mse'], fit.get('calibrated_mse', fit['mse']))


def _k_words(fit: dict) -> str:
    """Return stick-slip's MSE in words, saying whether its position was calibrated."""
    K = _stick_slip_mse(fit)
    return f'MSE {K:.4g}' + (' with its position calibrated' if K < fit['mse'] else '')


def _without_friction(best: dict, chain: dict, noise: float | None, why: str) -> FitVerdict:
    # Stick-slip beat an ideal valve, but not a valve with the timing and calibration
    # a real reading has: friction is not shown until it beats that one too.
    stages, F, K = chain_words(chain), chain['mse'], _stick_slip_mse(best)
    # Over a noisy reading that valve must also leave at most half of what stick-slip
    # leaves above the noise: the two tie within it (a sticking valve behind a dead time).
    above = share_above_noise(F, K, noise, best.get('samples'))
    if explains(chain, noise) and F <= K and (above is None or above >= MIN_IMPROVEMENT):
        return FitVerdict(False, 0.0, best['S'], (
            f'a valve without friction ({stages}) fits MV down to its noise (MSE {F:.4g}, '
            f'against {noise:.4g} from its sample-to-sample changes), at least as well as '
            f'stick-slip ({_k_words(best)}): what an ideal valve misses is timing or '
            f'calibration, not friction; {why}'), without_friction=stages)
    return _alike(best, chain, why, claimed=True)


def _alike(best: dict, chain: dict, why: str, claimed: bool = False) -> FitVerdict:
    # Stick-slip and a valve without friction fit about alike: neither claim is shown.
    F, words = chain['mse'], _k_words(best)
    if claimed:
        # Stick-slip beat an ideal valve by half, but not this valve.
        what = (f'stick-slip ({words}) removes under {100 * MIN_IMPROVEMENT:.0f} % of the '
                f'MSE of a valve without friction ({chain_words(chain)}, MSE {F:.4g}) or of '
                'its part above the noise, and that valve does not fit MV down to its noise '
                'and leave at most half of what stick-slip leaves above it')
    else:
        # No band by the ideal valve's test, yet stick-slip beats this valve.
        what = (f'stick-slip with a clear band and slip jump ({words}) fits MV better than '
                f'a valve without friction ({chain_words(chain)}, MSE {F:.4g}), but removes '
                f"under {100 * MIN_IMPROVEMENT:.0f} % of an ideal valve's MSE")
    return FitVerdict(None, 0.0, best['S'], (
        f'{what}: neither friction nor its absence is shown over timing and calibration; '
        f'--explain fits friction with them and tests both on held-out data; {why}'),
        code='frictionless_fits')


ANSWER = {True: 'stiction', False: 'no stiction', None: 'cannot tell'}


def combine(osc, sigs, fits, hammerstein=None, detection=None, sizing=None):
    """
    Return the report's ``stiction`` section.

    With fits (a measured MV) the fits decide; otherwise ``detection`` (the
    learned detector's :class:`Detection`) does, and the rule-based vote of
    :func:`from_signatures` is kept beside it as ``signature_vote``.  A size
    is given only when the record can be judged and any oscillation in it
    is resolvable; ``sizing`` (default ``detection``) is the detection of
    the stretch the signatures and the size read, where the answer pools
    several.
    """
    apparent = None
    ell = sigs.get('ellipse')
    sizing = detection if sizing is None else sizing
    sized = sizing is None or (sizing.judge.ok and not sizing.period_problem)
    # A PV-OP map that is no ellipse has a width, but not one of a valve's band.
    if ell is not None and ell.value is not None and sized and not no_ellipse(ell):
        apparent = ell.value
    extra = {}
    if fits:
        told = from_fits(fits)
        detected, score, why, apparent = told.detected, told.score, told.reason, told.size
        if told.play is not None:
            extra['play'] = told.play
        if told.code is not None:
            extra['cannot_tell'] = told.code
        if told.read_behind is not None:
            extra['read_behind'] = told.read_behind
        if told.without_friction is not None:
            # The fitted S is what a friction model makes of timing: no size to stand by.
            extra['without_friction'] = told.without_friction
            apparent = None
    else:
        vote = from_signatures(osc, sigs)
        extra['signature_vote'] = {'detected': vote[0], 'score': round(float(vote[1]), 4),
                                   'reason': vote[2]}
        if detection is not None:
            detected, why = detection.detected, detection.reason
            score = detection.probability if detection.probability is not None else 0.0
            extra['detector'] = detection.to_json()
            if not sized:
                extra['size_withheld'] = (sizing.period_problem or sizing.judge.reason)
        else:
            detected, score, why = vote
        if hammerstein is not None and getattr(hammerstein, 'reliable', False) and sized:
            apparent = hammerstein.S
    out = {'detected': detected, 'answer': ANSWER[detected],
           'probability': (detection.probability if detection is not None and not fits
                           else None),
           'score': round(float(score), 4), 'apparent_S': apparent,
           'reason': why, 'evidence': (detection.evidence if detection is not None and not fits
                                       else []), **extra,
           'oscillation': osc.to_json() if osc is not None else None,
           'signatures': {n: s.to_json() for n, s in sigs.items()}}
    if hammerstein is not None:
        out['hammerstein'] = hammerstein.to_json()
    return out


def refuse_still(stiction: dict, still: Still, sp_test: SetPointTest | None) -> None:
    """
    Make the verdict of a valve that never moved ``cannot tell``, as ``--explain`` says.

    A fit beats an ideal valve by far on such a record (MV = OP is wrong by all
    of OP's travel), yet three causes leave MV still, and two are not friction:
    a band wider than OP's travel, a valve held (no air, a handwheel), a dead
    or frozen position reading.  MV tells none of them apart; PV can rule the
    reading in or out where the set point moved (``sp_test``).  Where it rules
    the reading in (``mv_dead``), :func:`stiction_ros.analysis.pipeline.analyze`
    then judges the record from OP and PV.
    """
    moved = f'MV did not move while OP travelled {still.op_spread:.2g} %'
    if sp_test is None:
        code, why = 'mv_still', (f'{moved}: a friction band wider than that travel, a valve '
                                 'held (no air, a handwheel) or a dead position reading; MV '
                                 'tells none of them apart, a valve travel test does')
    elif sp_test.follows:
        code, why = 'mv_dead', (f'{moved}, but {sp_test.sentence()}; friction '
                                'cannot be read from MV, so the record is judged from OP and '
                                'PV, as one without MV')
    else:
        code, why = 'mv_still', (f'{moved}, and {sp_test.sentence()}; a friction '
                                 'band wider than that travel or a valve held (no air, a '
                                 'handwheel): a valve travel test tells which')
    # A band read from a still MV is no play either, nor a slip behind its timing:
    # nothing of how it moves is known.
    stiction.pop('play', None)
    stiction.pop('read_behind', None)
    stiction.update(detected=None, answer=ANSWER[None], cannot_tell=code, reason=why)
    if sp_test is not None:
        stiction['set_point_test'] = sp_test.to_json()
