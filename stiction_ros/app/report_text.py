"""
The analyzer's report as text: the JSON file and the verdict printed at the end.

Pure formatting of the report dict (see the README for its fields): nothing
here reads a recording, analyses or writes a file.  :func:`summary_text` is
what ``stiction-analyze`` prints for one recording; :func:`summary_line`, the
same verdict without the labelled lines, is each recording's row in a batch.
"""

from collections.abc import Sequence
import json
import math
import textwrap

import numpy as np

from stiction_ros.analysis.detection import BAND, probability_text
from stiction_ros.analysis.judged import judged_text
from stiction_ros.analysis.mismatch.sentences import explained_size

VERDICT_WORDS = {True: 'stiction', False: 'no stiction', None: 'cannot tell'}
FRICTION_WORDS = {'stiction': 'stiction claimed', 'backlash': 'backlash (play without stick)',
                  'none': 'not claimed'}


def _jsonable(x):
    """Return ``x`` with numpy scalars, tuples and non-finite floats made JSON-safe."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    return x


def to_json_text(report: dict) -> str:
    """Return the report as indented JSON (NaN written as null)."""
    return json.dumps(_jsonable(report), indent=2, ensure_ascii=False, allow_nan=False)


def summary_line(report: dict) -> str:
    """
    Return the verdict of one recording as a row of a batch (``stiction-analyze DIR``).

    Parameters
    ----------
    report : dict
        The report of one recording (``Analysis.report``).

    Returns
    -------
    str
        One line with the verdict and the fits, then indented warnings about
        the input (a file read only in part), the first two evidence lines
        and, after ``--explain``, the located and named mismatch, one per line.

    """
    st = report['stiction']
    fits = '; '.join(f'{f["model"]} S={f["S"]:.2f} J={f["J"]:.2f} MSE={f["mse"]:.4g}'
                     for f in report['fits'])
    line = _verdict(report) + (f'; {fits}' if fits else '')
    # A recording read only in part (a bag that ends early) says so in an audit too.
    for warning in (report.get('input') or {}).get('warnings') or []:
        line += f'\n  warning: {warning}'
    if report.get('mv_dead'):
        line += f'\n  MV set aside: {report["mv_dead"]["reason"]}'
    for ev in st.get('evidence', [])[:2]:
        line += f'\n  evidence: {ev}'
    if st.get('size_withheld'):
        line += f'\n  no size given: {st["size_withheld"]}'
    if st.get('size_caution'):
        line += f'\n  size caution: {st["size_caution"]}'
    if 'mismatch' in report and 'baseline' not in report:
        line += f'\nmismatch: cannot tell: {report["mismatch"]["explanation"]}'
    elif 'mismatch' in report:
        line += _mismatch_lines(report)
    return line


EVIDENCE_LINES = 3
LABEL_WIDTH = 10


def summary_text(report: dict, files: Sequence[str] = (), width: int | None = None) -> str:
    """
    Return the summary ``stiction-analyze`` prints at the end of one recording.

    Parameters
    ----------
    report : dict
        The report of one recording (``Analysis.report``).
    files : sequence of str
        The report files written (JSON, HTML), named on the ``report`` line.
    width : int, optional
        Wrap every line to this many characters (a terminal's width); None: no wrapping.

    Returns
    -------
    str
        The verdict with its probability or score, then one labelled line each:
        the fits, the evidence (which test saw what, and where), the apparent
        S and J with the model they come from, the excluded stretches and the
        report files; after ``--explain``, the located and named mismatch.

    """
    st = report['stiction']
    lines = [_verdict(report)]

    def add(label, text):
        lines.append(f'  {label + ":" if label else "":<{LABEL_WIDTH}}{text}')
    if report['fits']:
        add('fits', '; '.join(f'{f["model"]} S={f["S"]:.2f} J={f["J"]:.2f} MSE={f["mse"]:.4g}'
                              for f in report['fits']))
    if report.get('mv_dead'):
        add('MV', f'set aside: {report["mv_dead"]["reason"]}')
    evidence = st.get('evidence') or []
    # 'cannot tell' has its reason on the first line already.
    if not evidence and st['detected'] is not None:
        add('why', st.get('reason', ''))
    for ev in evidence[:EVIDENCE_LINES]:
        add('evidence', ev)
    if len(evidence) > EVIDENCE_LINES:
        more = len(evidence) - EVIDENCE_LINES
        add('', f'(and {more} more in the report)' if files else
            f'(and {more} more: --json FILE or --html FILE writes them all)')
    add('size', size_text(report))
    for warning in (report.get('input') or {}).get('warnings') or []:
        add('warning', warning)
    add('excluded', excluded_text(report))
    judged = judged_text(report)
    if judged:
        add('judged', judged)
    add('report', ', '.join(files) if files else 'no file written (--json FILE, --html FILE)')
    text = '\n'.join(lines)
    if 'mismatch' in report and 'baseline' not in report:
        text += f'\nmismatch: cannot tell: {report["mismatch"]["explanation"]}'
    elif 'mismatch' in report:
        text += _mismatch_lines(report)
    if width is None:
        return text
    out = []
    for line in text.split('\n'):
        # A labelled line continues under its text, any other one a little indented.
        indent = ' ' * (2 + LABEL_WIDTH if line.startswith('  ') else 4)
        out += textwrap.wrap(line, width, subsequent_indent=indent, break_on_hyphens=False,
                             break_long_words=False) or ['']
    return '\n'.join(out)


def _verdict(report):
    st = report['stiction']
    if st['detected'] is None:
        # Balanced evidence has a probability too; its reason states it.
        how = st.get('reason', '')
    elif st.get('probability') is not None:
        how = f'probability {probability_text(st["probability"], BAND)}'
    else:
        how = f'score {st["score"]:.2f}'
    name = report.get('name') or report['input'].get('path')
    return f'{name}: {VERDICT_WORDS[st["detected"]]} ({how})'


def size_text(report: dict) -> str:
    """Return the apparent S and J of ``report`` with the model they come from, or why none."""
    st = report['stiction']
    if report['fits']:
        best = min(report['fits'], key=lambda f: f['mse'])
        how = 'given' if best.get('source') == 'given' else 'identified from MV'
        ranges = ''
        if best.get('S_interval') and best.get('J_interval'):
            (s0, s1), (j0, j1) = best['S_interval'], best['J_interval']
            ranges = f'; 95 %: S {s0:.2f}-{s1:.2f}, J {j0:.2f}-{j1:.2f}'
        text = f'S={best["S"]:.2f} % J={best["J"]:.2f} % ({best["model"]}, {how}{ranges})'
        b = best.get('behind')
        if st.get('read_behind') and b:
            # The refit's size first: the plain fit read MV as on time and calibrated.
            (s0, s1), (j0, j1) = b['S_interval'], b['J_interval']
            text = (f'S={b["S"]:.2f} % J={b["J"]:.2f} % ({b["model"]}, identified from MV '
                    f'behind the reading\'s {st["read_behind"]}; 95 %: S {s0:.2f}-{s1:.2f}, J '
                    f'{j0:.2f}-{j1:.2f}); the plain fit, which reads MV on time: {text}')
        sized = explained_size(report)
        if sized:
            # The explained size first: read top-down, the plain fit's narrow ranges around
            # a size the lag or timing moved (J 0.00-0.02 for a J of 1.5) came first.
            text = (f'S={sized[1]:.2f} % J={sized[2]:.2f} % (with the physics --explain '
                    f'found in place: {sized[0]}); the plain fit, which leaves it out: '
                    f'{text}, ranges that hold only if it were right')
        m = report.get('mismatch') or {}
        if st.get('without_friction') and not m:
            text += (f'; a valve without friction ({st["without_friction"]}) explains MV: '
                     'this is what a friction model makes of it, not a friction size')
        if m.get('friction') is False:
            # Held out, no stick-slip beat the valve without it: the fit's S and J are what
            # a friction model makes of the rest, however narrow their range.
            text += ('; --explain finds play without a slip jump, not stick-slip'
                     if m.get('friction_kind') == 'backlash' else
                     '; --explain explains MV without friction: this is what a friction '
                     'model makes of what --explain found, not a friction size')
        caution = st.get('size_caution')
        return f'{text}; caution: {caution}' if caution else text
    withheld = st.get('size_withheld')
    if withheld:
        # 'cannot tell' says the same reason on the first line.
        return ('not given (the record cannot be judged)' if withheld == st.get('reason')
                else f'not given: {withheld}')
    ham, apparent = st.get('hammerstein'), st.get('apparent_S')
    if (apparent is not None and ham and ham.get('reliable')
            and math.isclose(ham['S'], apparent, rel_tol=1e-9)):
        return (f'S={ham["S"]:.2f} % J={ham["J"]:.2f} % (Hammerstein: kano and an ARX plant, '
                'from OP and PV)')
    if apparent is not None:
        return (f'S about {apparent:.2f} % of OP (width of the PV-OP ellipse); J needs MV or a '
                'reliable Hammerstein fit')
    if ham and ham.get('S') is not None:
        why = ham.get('reason') or 'see stiction.hammerstein.reason in the report'
        return (f'not given: the Hammerstein fit (S={ham["S"]:.2f} % J={ham["J"]:.2f} %) is '
                f'unreliable: {why}')
    return 'not given'


def excluded_text(report: dict) -> str:
    """Return how many stretches were excluded, how long in all, and why."""
    excluded = report.get('excluded') or []
    ts = report['sample_time']
    if not excluded:
        return f'nothing ({report["samples"]} samples at {ts:g} s)'
    n = sum(e['samples'] for e in excluded)
    reasons: dict = {}
    for e in excluded:
        reasons[e['reason']] = reasons.get(e['reason'], 0) + 1
    why = '; '.join(f'{r} ({k})' for r, k in sorted(reasons.items(), key=lambda x: -x[1]))
    return (f'{len(excluded)} stretch{"es" if len(excluded) > 1 else ""}, {n * ts:g} s in all '
            f'({100 * n / report["samples"]:.1f} % of {report["samples"]} samples): {why}')


# The explained model is called worse held out only beyond this ratio: a fraction of a
# per cent is the noise of the held-out part, not a failure.
WORSE = 1.05
# An MSE below this (%², an RMS of 1e-4 %, under the 0.001 % step S and J are fitted
# on) is the arithmetic's, not a model's: no worse to speak of.
ROUNDING_MSE = 1e-8


def _mismatch_lines(report):
    m, b = report['mismatch'], report['baseline']
    share = (report.get('holdout') or {}).get('share')
    # Fitted on the part before the held-out one, so not the fits' S and J above.
    part = f' (fitted on the first {100 * (1 - share):.0f} %)' if share else ''
    line = (f'\nplain model{part}: kano S={b["S"]:.3f} J={b["J"]:.3f} MSE fit '
            f'{b["mse_fit"]:.4g}')
    if m.get('regimes'):
        r = m['regimes'][0]
        line += (f'\nlocated: {r["regime"]} holds {100 * r["residual_share"]:.0f} % of the '
                 f'residual in {100 * r["sample_share"]:.0f} % of the samples')
    if m.get('regions'):
        g = m['regions'][0]
        line += (f'; worst stretch t={g["t_start"]:.0f}-{g["t_end"]:.0f} s ({g["regime"]}, '
                 f'{100 * g["residual_share"]:.0f} % of the residual)')
    line += _chain_lines(report)
    names = [e['id'] for e in m.get('effects', [])]
    told = ' '.join(e['sentence'] for e in m['effects']) if names else m['explanation']
    skew = report.get('clock_skew')
    recorded = (f' (on OP as recorded: {skew["plain_mse_holdout_as_recorded"]:.4g})'
                if skew else '')
    line += (f'\nmismatch: {", ".join(names) or m["effect"]} (confidence '
             f'{m["confidence"]:.2f}): {told}\nheld-out MSE: plain '
             f'{b["mse_holdout"]:.4g}{recorded} -> explained {m["mse_holdout"]:.4g}')
    sized = explained_size(report)
    if sized:
        # The size line above is the plain model's; the explained model sizes the valve
        # with the missing physics in place.
        name, s, j = sized
        rest = ', '.join(f'{k} {v:.4g}' for k, v in m['model']['params'].items()
                         if k not in ('S', 'J'))
        line += (f'\nexplained model: {name} S={s:.3f} J={j:.3f}'
                 + (f' ({rest})' if rest else '')
                 + ": the valve's own size, with the missing physics in place")
    if m.get('note'):
        line += f'\nnote: {m["note"]}'
    if names and m['mse_holdout'] > max(b['mse_holdout'] * WORSE, ROUNDING_MSE):
        why = (' (its prediction is read through the steps of the reading, so it misses by '
               'whole steps where a continuous one misses by part of a step; the steps are '
               "found from the reading's values, not from the MSE)"
               if names == ['quantisation'] else
               ': the effects named do not improve the fit on data they were not fitted '
               'to; read them with caution')
        line += (f'\nnote: the explained model is worse held out than the plain one '
                 f'({b["mse_holdout"]:.4g} -> {m["mse_holdout"]:.4g}){why}')
    if report['stiction'].get('detected') is not True and m.get('friction') is True:
        told = ('reads OP and PV and valve models without dead time, lead or calibration'
                if report['stiction'].get('detected') is False else
                'cannot tell from valve models without dead time, lead or calibration')
        line += (f'\nnote: the verdict above {told}; --explain, with the timing and '
                 'calibration it found in place, claims stiction from the valve position '
                 'itself, held out')
    if report['stiction'].get('detected') and m.get('friction') is False:
        found = ('play without a slip jump (backlash or a pure deadband) beats the best '
                 'valve without friction, stick-slip does not' if
                 m.get('friction_kind') == 'backlash' else
                 'no friction beats the best valve without friction here')
        line += ('\nnote: the stiction verdict above comes from valve models without dead '
                 f'time or calibration; {found}')
    return line


def _chain_lines(report):
    f = report.get('frictionless')
    if not f:
        return ''
    kind = report['mismatch'].get('friction_kind', 'none')
    # Its dead time and lags are whatever imitates the record best, however odd (a long
    # delay mimics a limit cycle): the comparison with the plain model says what they mean.
    plain = report['baseline']['mse_holdout']
    versus = ('worse than' if f['mse_holdout'] > plain else 'better than'
              if f['mse_holdout'] < plain else 'as good as')
    return (f'\nbest valve without friction: dead time {f["dead_time_s"]:.3g} s, lag '
            f'{f["lag_s"]:.3g} s, offset {f["offset"]:+.3g} %, gain {f["gain"]:.4g} (stages '
            f'kept: {", ".join(f["stages"]) or "none"}), held-out MSE {f["mse_holdout"]:.4g},'
            f' {versus} the plain friction model ({plain:.4g})'
            f'\nfriction: {FRICTION_WORDS[kind]}{_friction_because(report, f, kind)}')


def _friction_because(report, frictionless, kind):
    """Return the two held-out MSEs to read the friction line against (not the test)."""
    explained = report['mismatch'].get('mse_holdout')
    if explained is None or kind == 'none':
        return ''
    return (f' (held-out MSE of the explained model {explained:.4g}, of the best valve '
            f'without friction {frictionless["mse_holdout"]:.4g})')


def batch_row_text(row: dict) -> str:
    """Return the lines printed for one recording of a batch (its summary, or its error)."""
    if not row['ok']:
        return f'{row["input"]}: {"skipped" if row.get("skipped") else "error"}: {row["error"]}'
    # Recordings often share a tag name; the path tells them apart.
    first, *rest = row['summary'].split('\n')
    return '\n'.join([f'{row["input"]}: {first.split(": ", 1)[-1]}', *rest])
