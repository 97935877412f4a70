"""
Loops the simulator never draws: what the detector answers on them (``make probes``).

The detector learned from :mod:`stiction_ros.sim.corpus`, whose loops were
linear PI loops on linear plants, kept inside OP's range, when the first
probes were written (it has since drawn some of them), their controller run
once per exported sample.  A plant has more: equal-percentage valves whose
installed gain grows as they open, level controllers with a gap or an
error-squared law, loops tuned past stability, controllers that run many
times per historian sample, dead times longer than any it drew.
Each probe here draws one such family from its own generator (not the
corpus's, so nothing in it was tuned on), and :func:`run` reads every record
by the analyzer's own path (:func:`detect`).  A healthy record called
``stiction`` is the finding: a confident wrong answer on a kind of loop the
model never saw.  Nothing is fitted or chosen here; the model is the shipped
one.
"""

from dataclasses import dataclass, replace
import math
import time
from typing import Callable

import numpy as np

from stiction_ros._threads import pool_map
from stiction_ros.analysis.detection.detect import THRESHOLD

SAMPLES = 1500
SAMPLE_TIME = 10.0


@dataclass(frozen=True)
class ProbeRecord:
    """One probe loop as a historian would export it, with its truth."""

    op: np.ndarray
    pv: np.ndarray
    sp: np.ndarray
    sample_time: float
    integrating: bool
    label: bool


def _pi(kc: float, ti: float, ts: float, bias: float) -> Callable[[float], float]:
    """Return a positional PI step on the error, clamped to 0-100 % without wind-up."""
    state = {'i': bias}

    def step(e: float) -> float:
        raw = state['i'] + kc * e
        op = min(max(raw, 0.0), 100.0)
        if op == raw:
            state['i'] += kc * ts / ti * e
        return op
    return step


SETTLE = 20_000


def _settles(run: Callable[[float], np.ndarray]) -> bool:
    """
    Return whether a loop's linear version, started 1 off, settles (``run(kick)`` -> PV).

    Run for ``SETTLE`` samples, far longer than a record, so that a slow but
    stable loop is not taken for an unstable one.
    """
    pv = run(1.0)
    return bool(np.max(np.abs(pv[-500:])) < 1e-2)


def equal_percentage(seed: int, linear: bool = False) -> ProbeRecord:
    """
    Return a loop through an equal-percentage valve, tuned from normal to hot.

    The installed gain is ``R ** (x / 100)`` up to a constant (rangeability
    ``R``), scaled to 1 at the operating point; the loop is tuned by SIMC
    (lambda = theta) for that gain, times 0.8-2.5, then cooled until its
    linear version settles there.  Where loads or a cycle carry the valve
    further open the loop gain grows, and a hot tuning cycles, bounded by the
    gain falling again as it closes: a cycle of the characteristic, not of an
    unstable loop.  Half the records carry a sticky valve (Kano) instead.
    With ``linear`` the same loop (every draw the same) has a linear valve:
    the control that tells what the characteristic itself does.
    """
    from stiction_ros.models import create
    rng = np.random.default_rng([seed, 11])
    ts, n = SAMPLE_TIME, SAMPLES
    label = bool(rng.random() < 0.5)
    integrating = bool(rng.random() < 0.3)
    rangeability = rng.uniform(20.0, 50.0)
    tau = rng.uniform(1.0, 20.0) * ts
    delay = int(rng.integers(0, 6))
    gain = rng.uniform(0.5, 2.0)
    noise = rng.uniform(0.01, 0.2)
    hot = rng.uniform(0.8, 2.5)
    cycle = rng.uniform(0.5, 4.0) * np.sin(2.0 * np.pi * np.arange(n) / rng.uniform(20.0, 200.0))
    load = np.cumsum(rng.standard_normal(n)) * rng.uniform(0.01, 0.1)
    load = load + (cycle if rng.random() < 0.5 else 0.0)
    op0 = rng.uniform(20.0, 80.0)
    valve = None
    if label:
        stick = rng.uniform(1.0, 6.0)
        valve = create('kano', S=stick, J=stick * rng.uniform(0.2, 1.0))
        valve.reset(y0=op0)
    white = rng.standard_normal(n)
    ln_r = math.log(rangeability)
    if linear:
        # The limit of R ** (x / 100) as R -> 1, scaled to unit slope: x itself.
        ln_r = 0.0
    rate = gain / (50.0 * ts)
    # OP reaches the plant delay + 1 samples later, and the hold adds half a sample.
    theta = (delay + 1.5) * ts
    if integrating:
        kc0, ti = 1.0 / (rate * 2.0 * theta), 8.0 * theta
    else:
        kc0, ti = tau / (gain * 2.0 * theta), max(min(tau, 8.0 * theta), ts)

    def installed(x: float) -> float:
        # Unit slope at op0, so the tuning holds there and only there.
        x = min(max(x, 0.0), 100.0)
        if ln_r == 0.0:
            return x - op0
        return 100.0 / ln_r * (rangeability ** ((x - op0) / 100.0) - 1.0)

    def simulate(kc: float, kick: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        # kick: the linear version (no valve, characteristic, load or noise), 1 off.
        pi = _pi(kc, ti, ts, op0)
        a = math.exp(-ts / tau)
        x, queue = kick, [0.0] * (delay + 1)
        m = SETTLE if kick else n
        op, pv = np.empty(m), np.empty(m)
        for k in range(m):
            pv[k] = x + (0.0 if kick else noise * white[k])
            op[k] = pi(-pv[k])
            if kick:
                queue.append(op[k] - op0)
            else:
                position = valve.step(op[k]) if valve is not None else op[k]
                queue.append(installed(position) + load[k])
            u = queue.pop(0)
            x = x + rate * ts * u if integrating else a * x + (1.0 - a) * gain * u
        return op, pv
    for _ in range(30):
        if _settles(lambda kick: simulate(hot * kc0, kick)[1]):
            break
        hot *= 0.85
    op, pv = simulate(hot * kc0)
    return ProbeRecord(op, pv, np.zeros(n), ts, integrating, label)


def _level_loop(seed: int, law: Callable[[float, float], float]) -> ProbeRecord:
    """
    Return a healthy level loop (an integrating tank) under a nonlinear controller law.

    The PI gains are drawn, then cooled until the loop under the plain linear
    law settles, so that a cycle is the law's doing and not an unstable tuning.
    """
    rng = np.random.default_rng([seed, 13])
    ts, n = SAMPLE_TIME, SAMPLES
    rate = rng.uniform(0.002, 0.02)            # % level per % valve per second
    kc, ti = rng.uniform(0.5, 4.0), rng.uniform(300.0, 3000.0)
    gap = rng.uniform(1.0, 6.0)                 # % level
    noise, damping = rng.uniform(0.02, 0.3), rng.uniform(0.0, 0.8)
    delay = int(rng.integers(0, 3))
    mv0 = rng.uniform(30.0, 70.0)
    walk = np.cumsum(rng.standard_normal(n)) * rng.uniform(0.02, 0.2)
    inflow = mv0 + walk - walk[0]
    if rng.random() < 0.5:
        inflow[int(n * rng.uniform(0.2, 0.8)):] += rng.uniform(-5.0, 5.0)
    start = 50.0 + rng.uniform(-2.0, 2.0)
    white = rng.standard_normal(n)

    def simulate(kc: float, kick: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        # kick: the plain linear law, no load or noise, the level 1 off its set point.
        level = measured = 50.0 + kick if kick else start
        pi = _pi(kc, ti, ts, mv0)
        queue = [mv0] * (delay + 1)
        m = SETTLE if kick else n
        op, pv = np.empty(m), np.empty(m)
        for k in range(m):
            measured = damping * measured + (1.0 - damping) * level
            pv[k] = measured + (0.0 if kick else noise * white[k])
            # An outflow valve: a high level opens it (direct action).
            e = pv[k] - 50.0
            op[k] = pi(e if kick else law(e, gap))
            queue.append(op[k])
            level += rate * ts * ((mv0 if kick else inflow[k]) - queue.pop(0))
        return op, pv - 50.0 if kick else pv
    for _ in range(30):
        if _settles(lambda kick: simulate(kc, kick)[1]):
            break
        kc *= 0.85
    op, pv = simulate(kc)
    return ProbeRecord(op, pv, np.full(n, 50.0), ts, True, False)


def _gap(e: float, gap: float) -> float:
    # Inside the gap a tenth of the gain: averaging level control lets the tank swing.
    return 0.1 * e if abs(e) < gap else e - math.copysign(0.9 * gap, e)


def _squared(e: float, gap: float) -> float:
    return e * abs(e) / gap


def gap_level(seed: int) -> ProbeRecord:
    """Return a healthy level loop under a gap (two-gain) controller."""
    return _level_loop(seed, _gap)


def error_squared_level(seed: int) -> ProbeRecord:
    """Return a healthy level loop under an error-squared controller."""
    return _level_loop(seed, _squared)


def detuned(seed: int) -> ProbeRecord:
    """Return a corpus loop whose controller gain is raised 3-15 times (both labels)."""
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(seed)
    hot = float(np.random.default_rng([seed, 7]).uniform(3.0, 15.0))
    rec = simulate(replace(sc, Kc=sc.Kc * hot))
    return ProbeRecord(rec['op'], rec['pv'], rec['sp'], sc.sample_time, sc.integrating,
                       sc.label)


FAST = (3, 10)      # controller steps per historian sample, drawn per seed


def fast_controller(seed: int, average: bool = False, twin: bool = False) -> ProbeRecord:
    """
    Return a corpus loop whose controller runs 3-10 times per historian sample (both labels).

    A DCS runs its controllers every second or faster and the historian
    exports every 10 s; the corpus runs the controller at the export's
    sample.  Here the loop of ``draw_scenario(seed)``, tuned as drawn, runs
    3-10 times faster (``FAST``, drawn per seed; ``corpus.simulate``'s
    ``oversample``: noise and loads held over the sample), and the
    record is the value at each sample time, or with ``average`` the mean
    over each sample.  With ``twin`` the same loop runs once per sample, as
    the corpus draws it: the control that tells what the faster controller
    itself changes.
    """
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(seed)
    m = 1 if twin else int(np.random.default_rng([seed, 17]).integers(FAST[0], FAST[1] + 1))
    rec = simulate(sc, oversample=m, average=average)
    return ProbeRecord(rec['op'], rec['pv'], rec['sp'], sc.sample_time, sc.integrating,
                       sc.label)


LONGER = (6.0, 16.0)    # samples of dead time added to the drawn loop's, drawn per seed


def long_dead_time(seed: int, twin: bool = False) -> ProbeRecord:
    """
    Return a corpus loop whose dead time is 6-16 samples longer than drawn, tuned for it.

    The corpus draws at most 8 samples of dead time; a temperature loop logged
    every second, or a flow behind a long line, has more.  The loop of
    ``draw_scenario(seed)`` gets ``LONGER`` more samples (drawn per seed) and
    is tuned for its new dead time as the corpus tunes (a looser controller);
    all else drawn stays (a look-alike that must ring redraws its plant).
    With ``twin`` the loop as the corpus draws it: what the dead time changes.
    """
    from stiction_ros.sim.corpus import draw_scenario, simulate
    added = 0.0 if twin else float(np.random.default_rng([seed, 23]).uniform(*LONGER))
    sc = draw_scenario(seed, extra_delay=added)
    rec = simulate(sc)
    return ProbeRecord(rec['op'], rec['pv'], rec['sp'], sc.sample_time, sc.integrating,
                       sc.label)


def as_drawn(seed: int) -> ProbeRecord:
    """Return the corpus loop of ``seed`` as drawn: the twin of the probes that change it."""
    return long_dead_time(seed, twin=True)


# name, what it stands for, generator (twins share one: their records are read once).
PROBES: tuple[tuple[str, str, Callable[[int], ProbeRecord]], ...] = (
    ('equal percentage', 'an equal-percentage valve (rangeability 20-50), tuned 0.8-2.5 times '
     'hotter than SIMC for its gain at the operating point, then cooled until the linear '
     'loop settles there; half sticky (Kano, S 1-6 %)', equal_percentage),
    ('equal percentage, linear twin', 'the same loops, draw for draw, with a linear valve: '
     'what the characteristic itself changes', lambda seed: equal_percentage(seed, True)),
    ('gap level', 'a level loop whose controller has a tenth of its gain inside a gap of '
     '1-6 % (averaging level control), tuned so that the plain PI law settles; healthy',
     gap_level),
    ('error-squared level', 'a level loop under an error-squared PI law, tuned so that the '
     'plain PI law settles; healthy', error_squared_level),
    ('detuned', 'a corpus loop with its controller gain raised 3-15 times, both labels',
     detuned),
    ('fast controller', 'a corpus loop whose controller, valve and plant run 3-10 times per '
     'historian sample (loads, set point and measurement error held over the sample), '
     'exported as the value at each sample time; both labels', fast_controller),
    ('fast controller, averaged', 'the same loops, draw for draw, exported as the mean over '
     "each sample (a historian's interval average)",
     lambda seed: fast_controller(seed, average=True)),
    ('fast controller, twin', 'the same loops, draw for draw, with the controller run once '
     'per sample as the corpus runs it: what the faster controller itself changes',
     as_drawn),
    ('long dead time', 'a corpus loop whose dead time is 6-16 samples longer than drawn '
     '(the corpus draws at most 8), tuned for it; both labels', long_dead_time),
    ('long dead time, twin', 'the same loops, draw for draw, with the dead time drawn: what '
     'the longer dead time itself changes', as_drawn),
)


def _read(job: tuple[int, int]) -> tuple:
    from stiction_ros.analysis.detection.detect import detect
    j, seed = job
    r = PROBES[j][2](seed)
    d = detect(r.op, r.pv, r.sp, r.sample_time, r.integrating)
    return j, seed, r.label, d.answer, d.probability, '' if d.judge.ok else d.judge.code


@dataclass
class Probes:
    """The detector's answers on every probe record."""

    seeds: range
    answers: list       # (probe index, seed, label, answer, probability, refusal code)
    seconds: float

    def rows(self) -> list[dict]:
        """Return one row per probe and label: counts of each answer and refusal."""
        out = []
        for j, (name, what, _) in enumerate(PROBES):
            for label in (False, True):
                got = [a for a in self.answers if a[0] == j and a[2] == label]
                if not got:
                    continue
                p = np.array([np.nan if a[4] is None else a[4] for a in got])
                refusals: dict[str, int] = {}
                for a in got:
                    if a[5]:
                        refusals[a[5]] = refusals.get(a[5], 0) + 1
                out.append({'probe': name, 'what': what, 'label': label, 'records': len(got),
                            'stiction': sum(a[3] == 'stiction' for a in got),
                            'no_stiction': sum(a[3] == 'no stiction' for a in got),
                            'balanced': sum(a[3] == 'cannot tell' and not a[5] for a in got),
                            'refused': refusals, 'judged': int(np.isfinite(p).sum()),
                            'at_half': int(np.sum(np.nan_to_num(p, nan=0.0) >= THRESHOLD))})
        return out

    def to_json(self) -> dict:
        """Return the study as plain JSON types."""
        return {'seeds': [self.seeds.start, self.seeds.stop], 'seconds': round(self.seconds, 1),
                'rows': self.rows()}


def run(seeds: range, jobs: int = 1,
        say: Callable[[int, int, float], None] | None = None) -> Probes:
    """Return the detector's answers on every probe of :data:`PROBES` for ``seeds``."""
    t0, got = time.perf_counter(), []
    # A generator listed twice (the twins) is read under its first probe only.
    first = {j: next(i for i, p in enumerate(PROBES) if p[2] is PROBES[j][2])
             for j in range(len(PROBES))}
    jobs_list = [(j, s) for j in sorted(set(first.values())) for s in seeds]
    for i, r in enumerate(pool_map(_read, jobs_list, jobs, chunksize=4), 1):
        got += [(j, *r[1:]) for j in range(len(PROBES)) if first[j] == r[0]]
        if say is not None:
            say(i, len(jobs_list), time.perf_counter() - t0)
    got.sort(key=lambda a: a[0])
    return Probes(seeds, got, time.perf_counter() - t0)
