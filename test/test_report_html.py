"""
The HTML report as a reader gets it: self-contained, every figure loads, units, no raw dumps.

Three real pages, each from a simulated loop analysed by the command as an
engineer runs it: Table 2.1's undershoot case with --explain (a valve the
model fits to an MSE near 0), the loop of the demo's second part whose valve
hides a measurement lag (friction candidates that pass but are not named),
and the undershoot case without MV (the OP/PV detector and the Hammerstein
fit): report_pages.py writes them once per test session.  The page is read
with html.parser, as a browser's parser would see it (test_report_browser.py
opens the same pages in headless Chromium).
"""

import base64
from html.parser import HTMLParser
import re
import struct
import zlib

import numpy as np
import pytest

from stiction_ros.analysis.detection.detect import BAND
from stiction_ros.app.analyze import analyze_file, AnalyzeOptions
from stiction_ros.app.report_files import landscapes
from stiction_ros.viz.figures import landscape_colours
from stiction_ros.viz.report_html import CAPTIONS

PNG_MAGIC = b'\x89PNG\r\n\x1a\n'
CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
# A number as it shows in text: digits, a decimal part, an exponent.
NUMBER = re.compile(r'\d+(?:\.\d+)?(?:[eE][-+]?\d+)?')
URL_ATTRS = ('src', 'href', 'srcset', 'action', 'data', 'poster', 'background', 'formaction')


@pytest.fixture(scope='module')
def pages(report_pages):
    return report_pages


class Page(HTMLParser):
    """Everything on a page a reader's browser would load or show."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.tags, self.text, self.css, self.tables = [], [], [], []
        self._in = []
        self._row = None

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))
        if tag not in ('br', 'img', 'meta', 'wbr', 'link', 'input', 'hr'):
            self._in.append(tag)
        if tag == 'table':
            self.tables.append([])
        elif tag == 'tr':
            self._row = []
            self.tables[-1].append(self._row)
        elif tag in ('td', 'th'):
            self._row.append('')

    def handle_endtag(self, tag):
        if tag in self._in:
            while self._in.pop() != tag:
                pass

    def handle_data(self, data):
        if self._in and self._in[-1] in ('style', 'script'):
            self.css.append(data)
            return
        self.text.append(data)
        if self._row and ('td' in self._in or 'th' in self._in):
            self._row[-1] += data

    def table_with(self, header):
        """Return the rows of the first table whose header row holds ``header``."""
        return next(t for t in self.tables if header in t[0])


def parse(path):
    p = Page()
    p.feed(path.read_text(encoding='utf-8'))
    p.close()
    return p


def words(parsed):
    # A number and its unit are joined by a no-break space; sentences are read as words.
    return ' '.join(parsed.text).replace('\u00a0', ' ')


def check_png(data):
    """Fail unless ``data`` is a whole PNG: every chunk's CRC and the pixels' size agree."""
    assert data[:8] == PNG_MAGIC
    pos, chunks, idat = 8, [], b''
    while pos < len(data):
        (length,) = struct.unpack('>I', data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack('>I', data[pos + 8 + length:pos + 12 + length])
        assert zlib.crc32(kind + body) == crc, f'bad CRC in chunk {kind!r}'
        chunks.append(kind)
        idat += body if kind == b'IDAT' else b''
        if kind == b'IHDR':
            width, height, depth, colour, _, _, interlace = struct.unpack('>IIBBBBB', body)
        pos += 12 + length
    assert chunks[0] == b'IHDR' and chunks[-1] == b'IEND' and pos == len(data)
    assert interlace == 0 and width > 100 and height > 100
    row = 1 + (width * CHANNELS[colour] * depth + 7) // 8
    assert len(zlib.decompress(idat)) == height * row
    return width, height


def images(path, parsed):
    """Return the bytes of every <img> of the page, checked to load."""
    out = []
    for tag, attrs in parsed.tags:
        if tag != 'img':
            continue
        src = attrs.get('src') or ''
        assert attrs.get('alt'), 'an image without alt text'
        if src.startswith('data:image/png;base64,'):
            raw = base64.b64decode(src.split(',', 1)[1], validate=True)
        else:
            # A file beside the page, by a relative path.
            assert src and ':' not in src and not src.startswith('/'), src
            raw = (path.parent / src).read_bytes()
        check_png(raw)
        out.append(raw)
    return out


def significant_digits(token):
    mantissa = re.split('[eE]', token)[0]
    digits = mantissa.replace('.', '').lstrip('0')
    if '.' not in mantissa:
        digits = digits.rstrip('0')  # 1000000 holds one significant digit
    return len(digits)


@pytest.mark.parametrize('name', ['undershoot', 'hidden', 'no_mv'])
@pytest.mark.slow
def test_the_page_loads_nothing_from_outside_and_every_figure_is_embedded(pages, name):
    path, _ = pages[name]
    parsed = parse(path)
    for tag, attrs in parsed.tags:
        assert not (tag == 'script' and 'src' in attrs), 'a script loaded from elsewhere'
        assert not (tag == 'link' and attrs.get('rel') == 'stylesheet'), 'an outside style'
        for key in URL_ATTRS:
            value = (attrs.get(key) or '').strip().lower()
            assert not value.startswith(('http:', 'https:', '//', 'ftp:')), (tag, key, value)
        parsed.css.append(attrs.get('style') or '')
    css = ' '.join(parsed.css).lower()
    assert '@import' not in css
    for target in re.findall(r'url\(\s*[\'"]?([^\'")]*)', css):
        assert not target.strip().startswith(('http:', 'https:', '//')), target
    shown = images(path, parsed)
    drawn = {p.name: p.read_bytes() for p in (path.parent / 'r_figures').glob('*.png')}
    # Every figure drawn is on the page, and the page shows nothing else.
    assert sorted(shown) == sorted(drawn.values())
    expected = {'trends.png', 'maps.png', 'signatures.png'}
    expected |= {'landscape_kano.png', 'landscape_choudhury.png', 'mismatch.png'} \
        if name != 'no_mv' else set()
    assert set(drawn) == expected
    # Each figure says what it shows and in which units.
    captions = path.read_text().count('<figcaption>')
    assert captions == len(shown)


@pytest.mark.parametrize('name', ['undershoot', 'hidden', 'no_mv'])
def test_no_raw_dumps_and_no_long_numbers_anywhere_in_the_text(pages, name):
    path, report = pages[name]
    text = ' '.join(parse(path).text)
    for raw in ('{', '}', "['", '["'):
        assert raw not in text, f'{raw!r} on the page of {name}'
    # Python's words for missing values, as a dump of the report would print them.
    assert not re.findall(r'\b(?:None|True|False|nan|inf)\b', text)
    numbers = NUMBER.findall(text)
    assert len(numbers) > 50  # the page is full of figures; the check reads them all
    long = [n for n in numbers if significant_digits(n) > 6]
    assert not long, f'numbers with more than 6 significant digits: {long[:5]}'
    # Floats from the report reach the page rounded, never as Python prints them.
    period = report['stiction']['oscillation']['period_s']
    assert repr(period) not in text and f'{period:.4g}\u00a0s' in text


def test_oscillation_and_fits_are_tables_with_units(pages):
    path, report = pages['undershoot']
    parsed = parse(path)
    osc = {row[0]: row[1] for row in parsed.table_with('quantity')}
    o = report['stiction']['oscillation']
    assert osc['period'] == f'{o["period_s"]:.4g}\u00a0s'
    assert osc['amplitude'] == f'{o["amplitude"]:.4g}\u00a0PV units'
    assert osc['regularity'] == f'{o["regularity"]:.3g}'
    fits = parsed.table_with('model')
    assert 'MSE (%²)' in fits[0] and 'S 95 % range' in fits[0]
    kano = next(r for r in fits if r[0] == 'kano')
    assert kano[1].endswith('\u00a0%') and kano[2].endswith('\u00a0%')
    assert kano[fits[0].index('S 95 % range')].endswith('\u00a0%')
    sigs = parsed.table_with('signature')
    horch = next(r for r in sigs if r[0] == 'horch')
    assert horch[2].endswith('deg') and horch[3] == '≥ 120\u00a0deg'
    text = words(parsed)
    assert 'PV and SP in PV units' in text
    # The verdict's rule, next to it, from the constants that decide it.
    assert 'starts at or above 0.2 %' in text and 'at least 50 % below' in text


def test_the_hammerstein_fit_and_the_detector_are_tables_and_rules_not_dumps(pages):
    path, report = pages['no_mv']
    parsed = parse(path)
    ham = report['stiction']['hammerstein']
    rows = {row[0]: row[1:] for row in parsed.table_with('range or meaning')}
    assert rows['S'][0] == f'{ham["S"]:.4g}\u00a0%'
    low, high = ham['S_interval']
    assert rows['S'][1] == f'{low:.4g} to {high:.4g}\u00a0%'
    assert 'PV units per % of OP' in rows['plant (ARX)'][1]
    lo, hi = BAND
    assert (f'calibrated probability is at or above {hi}, no stiction below {lo}, and cannot '
            'tell between') in words(parsed)
    leaned = report['stiction']['detector']['leaned_on']
    rests = {row[0]: row[1:] for row in parsed.table_with('moved the score by')[1:]}
    assert [c['feature'] for c in leaned['contributions']] == list(rests)
    for c in leaned['contributions']:
        assert rests[c['feature']][1] == f'{c["log_odds"]:+.2f}'
    # The jump's ratio is read against the chi-square point it is tested by.
    jump = ham['details']['jump_likelihood_ratio']
    assert jump is not None
    meaning = rows['likelihood ratio, slip jump vs deadband (J = 0)'][1]
    assert meaning.startswith('a figure, not a test') and '18 with a sticky one' in meaning
    # Without MV the maps figure has the PV-OP panel alone, and says so.
    text = words(parsed)
    assert CAPTIONS['maps_pv'] in text
    assert 'Left: MV against OP' not in text


def test_each_candidate_says_why_it_was_or_was_not_named(pages):
    path, report = pages['hidden']
    cands = report['candidates']
    named = report['mismatch']['effect']
    passing = [c['effect'] for c in cands if c['score'] > 1.0]
    # The case the reader asked about: more than one candidate above 1, one named.
    assert named == 'measurement_lag' and len(passing) >= 2
    parsed = parse(path)
    table = parsed.table_with('score (LR / threshold)')
    decision = {row[0]: row[-1] for row in table[1:]}
    assert set(decision) == {c['effect'] for c in cands}
    for c in cands:
        why = decision[c['effect']]
        if c['effect'] == named:
            assert why.startswith('named: the highest score')
        elif c['score'] > 1.0:
            assert why == f'passes, not named: {named} scores higher'
        else:
            assert why == 'below its threshold'
    text = words(parsed)
    # The rule states the real thresholds: chi-square points, bootstrap margin, replicates.
    boot = report['mismatch']['bootstrap']
    assert 'larger of the chi-square 99.9 % point' in text and '10.83 for one' in text
    assert f'{boot["margin"]:g} times the largest LR' in text
    assert f'{boot["replicates"]} effect-free bootstrap replicates' in text
    others = [e for e in passing if e != named]
    assert all(f'{e} (' in text for e in others) and 'none was tested on top of it' in text
    assert 'The held-out part decides nothing here' in text


def test_the_landscape_of_a_near_zero_mse_is_coloured_relative_to_its_minimum(pages):
    analysis = analyze_file(AnalyzeOptions(str(pages['csv']), model='kano'))
    assert analysis.fits[0].mse < 1e-3  # the case: a valve the model fits exactly
    (land,) = landscapes(analysis)
    c = landscape_colours(land)
    # The best cell is 0 and the map spans decades above it.  This fit is exact (MSE at
    # the floor), so the colours count from the best cell off the floor ...
    mse = np.asarray(land['mse'])
    assert analysis.fits[0].mse == 0.0 and c['exact'] == 1
    assert np.min(c['value']) == 0.0 and c['vmax'] >= 2.0
    assert c['mse_min'] == pytest.approx(np.min(mse[mse > np.min(mse)]))
    # ... and no flat plateau: at most 5 % of the cells sit at the ceiling (one colour).
    # Capped at 1e4 x MSE_min, as it was, 46 % of this map did.
    assert np.mean(c['over']) <= 0.05
    inner = c['value'][~c['over']]
    assert np.percentile(inner, 90) - np.percentile(inner, 10) > 1.0
    png = (pages['undershoot'][0].parent / 'r_figures' / 'landscape_kano.png').read_bytes()
    assert check_png(png)[0] > 400
    # The file beside the page is the one the page embeds.
    assert base64.b64encode(png).decode() in pages['undershoot'][0].read_text()


def test_a_loop_without_a_cycle_shows_no_measured_zeros():
    from stiction_ros.viz.report_html import _oscillation
    html = '\n'.join(_oscillation({'oscillating': False, 'period_s': None, 'amplitude': 0.0,
                                   'regularity': 0.0, 'n_cycles': 0.0,
                                   'reason': 'no regular cycle'}))
    assert 'no regular cycle' in html
    assert 'amplitude' not in html and 'cycles in the record' not in html


def test_an_irregular_candidate_period_is_not_shown_as_the_loops_cycle():
    from stiction_ros.viz.report_html import _oscillation
    html = '\n'.join(_oscillation({'oscillating': False, 'period_s': 412.0, 'amplitude': 0.3,
                                   'regularity': 0.4, 'n_cycles': 21.0,
                                   'reason': 'regularity 0.40 < 1'}))
    assert '<td>candidate period</td>' in html and 'not a cycle of the loop' in html
    assert '<td>period</td>' not in html and '<td>candidate cycles in the record</td>' in html


def test_the_trends_mark_where_the_detectors_evidence_points(pages, tmp_path):
    from stiction_ros.viz.figures import detector_marks, trends_panels
    csv_path = tmp_path / 'no_mv.csv'
    csv_path.write_bytes((pages['no_mv'][0].parent.parent / 'no_mv.csv').read_bytes())
    analysis = analyze_file(AnalyzeOptions(str(csv_path)))
    periods, slips = detector_marks(analysis)
    evidence = ' '.join(analysis.detection.evidence)
    named = re.findall(r'stuck period (\d+) s-(\d+) s', evidence)
    assert named and slips
    assert {(float(a), float(b)) for a, b in named} <= set(periods)
    pv_axes = trends_panels(analysis).axes[1]
    # One shaded span per stuck period, where the detector put it; a dotted line per slip.
    starts = sorted(p.get_x() for p in pv_axes.patches if p.get_facecolor()[:3] != (0.85,) * 3)
    assert starts == sorted(a for a, _ in periods)
    dotted = [ln.get_xdata()[0] for ln in pv_axes.get_lines() if ln.get_linestyle() == ':']
    assert sorted(dotted) == sorted(slips)


def test_the_size_after_explain_is_the_explained_models_wherever_it_is_read(pages):
    from stiction_ros.app.report_text import size_text
    path, report = pages['hidden']
    params = report['mismatch']['model']['params']
    assert report['mismatch']['model']['name'] == 'kano+measurement_lag'
    # The plain fit reads the lag as friction; the explained model sizes the valve itself.
    assert abs(report['fits'][0]['J'] - params['J']) > 0.3
    text = words(parse(path))
    assert (f"the valve itself has S {params['S']:.4g} % and J {params['J']:.4g} %"
            in text)
    assert size_text(report).startswith(
        f"S={params['S']:.2f} % J={params['J']:.2f} % (with the physics --explain found in "
        'place: kano+measurement_lag); the plain fit, which leaves it out: ')
    # Without a named effect the size is the fits' alone.
    assert 'in place' not in size_text(pages['undershoot'][1])


@pytest.mark.parametrize('name', ['undershoot', 'no_mv'])
def test_the_page_says_where_its_times_count_from_and_what_wrote_it(pages, name):
    from stiction_ros import __version__
    path, report = pages[name]
    text = words(parse(path))
    assert report['start_time'] is None  # a simulated CSV of seconds: no clock
    assert 'The record gives no clock time; every time on this page (s) counts from its ' \
        'first sample.' in text
    assert f'by stiction_ros {__version__}' in text
    model = (report['stiction'].get('detector') or {}).get('model')
    if model:
        assert f"detector {model['file']} version {model['version']}" in text
    else:  # with MV the fits decide, and no detector model was read
        assert ' version ' not in text


def test_an_exact_fits_landscape_is_coloured_by_the_cells_around_it():
    # MSE at the floor (an exact fit) made every other cell ten decades up: one colour.
    from stiction_ros.analysis.identify import EXACT_MSE
    s, j = np.linspace(4.5, 5.5, 11), np.linspace(1.5, 2.5, 11)
    mse = 1e-3 * (((s[:, None] - 5.0) / 0.1) ** 2 + ((j[None, :] - 2.0) / 0.3) ** 2)
    mse = np.maximum(mse, EXACT_MSE)
    c = landscape_colours({'S': s, 'J': j, 'mse': mse, 'ceiling': None})
    assert c['exact'] == 1 and c['value'][5, 5] == 0.0
    assert c['mse_min'] == pytest.approx(np.min(mse[mse > EXACT_MSE]))
    # The cells around it span the decades they differ by, not twelve.
    assert 1.5 < c['vmax'] < 3.0 and np.min(c['value'][mse > EXACT_MSE]) == 0.0


def test_a_record_with_a_clock_says_where_its_times_count_from():
    from stiction_ros.viz.report_html import _provenance
    line = _provenance({'start_time': '2024-09-01T21:55:00', 'stiction': {}})
    assert 'The record starts at 2024-09-01T21:55:00; every time on this page (s) counts ' \
        'from there.' in line
    # A detector file without a version says nothing of one rather than "version None".
    bare = _provenance({'start_time': None, 'stiction': {'detector': {'model': {
        'file': 'stiction_detector.npz'}}}})
    assert 'detector stiction_detector.npz' in bare and 'None' not in bare
