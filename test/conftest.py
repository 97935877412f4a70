"""Test-wide settings: DDS stays on this machine, each run on its own domain."""

from collections import Counter
import os

import pytest

# Before any test module loads NumPy: the BLAS kernels the package pins (_blas.py),
# so that one test file run alone computes what the whole suite does.
import stiction_ros  # noqa: F401,I100
from stiction_ros._threads import one_blas_thread  # noqa: I100

# Workers of pytest-xdist share the cores as a pool's workers do: one BLAS and OpenMP
# thread each (_threads.py), which the nodes and commands they start inherit.  With a
# thread per core in each worker, a test of least-squares fits took 34.7 s against 7.8 s.
if int(os.environ.get('PYTEST_XDIST_WORKER_COUNT', '1')) > 1:
    one_blas_thread()

# Set before any test imports rclpy, and inherited by every node process the
# tests start: discovery only on 127.0.0.1, and a domain of our own so that
# parallel runs on the same machine do not see each other.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(1 + os.getpid() % 100))
# Under pytest-xdist each worker inherits the run's domain from the controller;
# worker gwN moves N domains on, so two workers' nodes never meet either.
_WORKER = os.environ.get('PYTEST_XDIST_WORKER', '')
if _WORKER.startswith('gw') and _WORKER[2:].isdigit():
    os.environ['ROS_DOMAIN_ID'] = str((int(os.environ['ROS_DOMAIN_ID']) + int(_WORKER[2:])) % 102)
os.environ.setdefault('MPLBACKEND', 'Agg')
# The loop launcher's choice for its nodes (cli/loop.py), for every node the tests start:
# Fast DDS's shared-memory transport hung a node now and then under load.
os.environ.setdefault('FASTDDS_BUILTIN_TRANSPORTS', 'UDPv4')


def pytest_collection_modifyitems(items):
    """Run the files that hold a slow test first: xdist then ends on short files, not one long."""
    slow = {item.path for item in items if item.get_closest_marker('slow')}
    items.sort(key=lambda item: item.path not in slow)


@pytest.fixture(scope='module')
def probe(request):
    """Return an rclpy node of the test module's own, spinning in a thread."""
    # Imported here: most tests must run, and some must prove they run, without rclpy.
    import rclpy
    from ros_helpers import Probe
    if not rclpy.ok():
        rclpy.init()
    p = Probe(request.module.__name__.rsplit('.', 1)[-1] + '_probe')
    yield p
    p.close()
    rclpy.try_shutdown()


@pytest.fixture(scope='session')
def report_pages(tmp_path_factory):
    """Return the three report pages of report_pages.py, written once per session."""
    from report_pages import write_pages
    return write_pages(tmp_path_factory.mktemp('report_pages'))


# The fuzz counts of every xdist worker, summed in the controller.
_FUZZ = {'tried': Counter(), 'outcomes': Counter()}


def _fuzz_counts():
    import sys
    fuzz = sys.modules.get('test_fuzz_inputs')
    if fuzz is None:
        return Counter(), Counter()
    return fuzz.TRIED, fuzz.OUTCOMES


def pytest_sessionfinish(session):
    """On an xdist worker: hand its fuzz counts to the controller."""
    out = getattr(session.config, 'workeroutput', None)
    if out is not None:
        tried, outcomes = _fuzz_counts()
        out['fuzz_tried'], out['fuzz_outcomes'] = dict(tried), dict(outcomes)


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    """In the xdist controller: add a finished worker's fuzz counts."""
    out = getattr(node, 'workeroutput', {})
    _FUZZ['tried'].update(out.get('fuzz_tried', {}))
    _FUZZ['outcomes'].update(out.get('fuzz_outcomes', {}))


def pytest_terminal_summary(terminalreporter):
    """Say how many inputs the fuzz suite tried, and how each ended."""
    tried, outcomes = _fuzz_counts()
    tried, outcomes = tried + _FUZZ['tried'], outcomes + _FUZZ['outcomes']
    if not tried:
        return
    terminalreporter.write_line(f'fuzz: {sum(tried.values())} inputs tried')
    for kind, n in sorted(tried.items()):
        ends = ', '.join(f'{outcomes[f"{kind}: {how}"]} {how}s'
                         for how in ('result', 'one-line error'))
        terminalreporter.write_line(f'  {kind}: {n} ({ends})')
