"""
Real HTML report pages for the report tests, written once per test session.

Three pages, each from a simulated loop analysed by the command as an
engineer runs it: Table 2.1's undershoot case with --explain (a valve the
model fits to an MSE near 0), the loop of the demo's second part whose valve
hides a measurement lag (friction candidates that pass but are not named),
and the undershoot case without MV (the OP/PV detector and the Hammerstein
fit).  test_report_html.py reads them as a parser, test_report_browser.py in
headless Chromium.
"""

import csv
import json
import subprocess
import sys


def run(module, *args):
    res = subprocess.run([sys.executable, '-m', f'stiction_ros.cli.{module}', *map(str, args)],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    return res


def pages_at_once(jobs):
    """Write the page of each ``(folder, csv, options)`` in ``jobs``, all at once; return them."""
    # The suite runs one test at a time: the analyses share the machine's other core.
    procs = []
    for folder, csv_path, options in jobs:
        args = [csv_path, '--html', folder / 'r.html', '--json', folder / 'r.json', '--quiet',
                *options]
        procs.append(subprocess.Popen(
            [sys.executable, '-m', 'stiction_ros.cli.analyze', *map(str, args)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
    for proc in procs:
        _, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, err
    return [(folder / 'r.html', json.loads((folder / 'r.json').read_text()))
            for folder, _, _ in jobs]


def write_pages(d):
    """Write the three pages under folder ``d``; return {name: (html path, report)} and 'csv'."""
    run('sim', 'concentration_loop.yaml', '--case', 'undershoot', '--quiet', '-o',
        d / 'undershoot.csv')
    run('sim', 'hidden_effect_loop.yaml', '--quiet', '-o', d / 'hidden.csv')
    with open(d / 'undershoot.csv', newline='') as src, \
            open(d / 'no_mv.csv', 'w', newline='') as dst:
        rows = list(csv.reader(src))
        keep = [i for i, name in enumerate(rows[0]) if name != 'mv']
        csv.writer(dst).writerows([[r[i] for i in keep] for r in rows])
    names = ('undershoot', 'hidden', 'no_mv')
    for name in names:
        (d / name).mkdir()
    done = pages_at_once([(d / 'undershoot', d / 'undershoot.csv', ['--explain', '--jobs', '1']),
                          (d / 'hidden', d / 'hidden.csv', ['--explain', '--jobs', '1']),
                          (d / 'no_mv', d / 'no_mv.csv', [])])
    out = dict(zip(names, done))
    out['csv'] = d / 'undershoot.csv'
    return out
