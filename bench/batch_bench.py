"""Many recordings at once: recordings per second with 1 and 2 worker processes."""

import contextlib
import io
import time

from stiction_ros.cli.analyze import main as analyze


def bench_batch(folder, jobs=(1, 2)):
    """Return [(jobs, recordings, seconds)] for ``stiction-analyze FOLDER --jobs N``."""
    from stiction_ros.app.batch import expand
    n = len(expand(str(folder)))
    rows = []
    for j in jobs:
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            analyze([str(folder), '--jobs', str(j), '--quiet'])
        rows.append((j, n, time.perf_counter() - t0))
    return rows


def markdown(rows, folder_label):
    """Return the BENCHMARKS.md section."""
    base = rows[0][1] / rows[0][2]
    lines = ['## Many recordings: `stiction-analyze FOLDER --jobs N`', '',
             f'{folder_label}: every recording analysed on its own (verdict, signatures, '
             'S and J where there is an MV), whole command timed including the worker start.',
             '', '| workers | recordings | seconds | recordings/s | scaling vs 1 |',
             '|---|---|---|---|---|']
    lines += [f'| {j} | {n} | {t:.1f} | {n / t:.2f} | {(n / t) / base:.2f} |'
              for j, n, t in rows]
    lines += ['', 'The same code runs on a Dask cluster with `--scheduler ADDRESS` (tested on a '
              '`LocalCluster`).', '']
    return lines
