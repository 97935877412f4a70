"""The repository is a genuine ament_python package that colcon builds into the ament layout."""

import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXECUTABLES = ('stiction-sim', 'stiction-study', 'stiction-bag', 'controller', 'valve', 'plant',
               'recorder', 'sim_clock', 'loop')


def test_package_xml_is_format_3_ament_python():
    root = ET.parse(ROOT / 'package.xml').getroot()
    assert root.get('format') == '3'
    assert root.findtext('name') == 'stiction_ros'
    assert root.find('export/build_type').text == 'ament_python'
    deps = {e.text for e in root.findall('exec_depend')}
    assert {'rclpy', 'std_msgs', 'diagnostic_msgs'} <= deps
    tests = {e.text for e in root.findall('test_depend')}
    assert {'ament_flake8', 'ament_pep257', 'python3-pytest'} <= tests


@pytest.fixture(scope='module')
def colcon_install(tmp_path_factory):
    colcon = Path(sys.executable).with_name('colcon')
    if not colcon.exists():
        colcon = shutil.which('colcon')
    assert colcon, 'colcon is installed by tools/bootstrap.sh (requirements/test.txt)'
    ws = tmp_path_factory.mktemp('ws')
    src = ws / 'src' / 'stiction_ros'
    files = subprocess.run(['git', 'ls-files', '-co', '--exclude-standard'], cwd=ROOT,
                           capture_output=True, text=True, check=True).stdout.split()
    for f in files:
        if (ROOT / f).is_file():
            (src / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / f, src / f)
    # The analyzer's ahead-of-time build (about 20 s) is tested in the venv
    # (test_ahead_of_time); here the install's numba cache is what is checked.
    run = subprocess.run([str(colcon), 'build', '--base-paths', 'src'], cwd=ws,
                         capture_output=True, text=True, timeout=300,
                         env={**os.environ, 'STICTION_ROS_JIT_ONLY': '1'})
    assert run.returncode == 0, run.stdout + run.stderr
    return ws / 'install' / 'stiction_ros'


@pytest.mark.slow
def test_colcon_build_gives_the_ament_layout(colcon_install):
    prefix = colcon_install
    marker = prefix / 'share/ament_index/resource_index/packages/stiction_ros'
    assert marker.is_file()
    assert (prefix / 'share/stiction_ros/package.xml').is_file()
    assert (prefix / 'share/stiction_ros/config/concentration_loop.yaml').is_file()
    for node in ('plant', 'controller', 'valve'):
        params = f'share/stiction_ros/config/params/concentration_undershoot/{node}.params.yaml'
        assert (prefix / params).is_file()
    shipped = list((ROOT / 'config/params').glob('*/*.params.yaml'))
    installed = list((prefix / 'share/stiction_ros/config/params').glob('*/*.params.yaml'))
    assert len(installed) == len(shipped) >= 15
    assert (prefix / 'share/stiction_ros/launch/loop.launch.py').is_file()
    for exe in EXECUTABLES:
        path = prefix / 'lib/stiction_ros' / exe
        assert path.is_file() and os.access(path, os.X_OK), path


def test_the_install_carries_the_stiction_detector_and_loads_it(colcon_install, tmp_path):
    site = next((colcon_install / 'lib').glob('python3*/site-packages'))
    assert (site / 'stiction_ros/resources/stiction_detector.npz').is_file()
    code = ('import stiction_ros.analysis.detection as d; m = d.load_model(); '
            'print(d.model_file.DEFAULT_PATH, len(m.tree_start))')
    run = subprocess.run([sys.executable, '-c', code], cwd=tmp_path, capture_output=True,
                         text=True, timeout=60, env=dict(os.environ, PYTHONPATH=str(site)))
    assert run.returncode == 0, run.stderr
    # Read from the install, not from the source tree.
    assert str(site) in run.stdout and int(run.stdout.split()[-1]) > 0


def test_installed_executable_runs_as_ros2_run_would_find_it(colcon_install, tmp_path):
    # `ros2 run PKG EXE` = ament index lookup of PKG's prefix, then PREFIX/lib/PKG/EXE.
    site = next((colcon_install / 'lib').glob('python3*/site-packages'))
    env = dict(os.environ, AMENT_PREFIX_PATH=str(colcon_install), PYTHONPATH=str(site))
    lookup = ('from ament_index_python.packages import get_package_prefix;'
              'print(get_package_prefix("stiction_ros"))')
    prefix = subprocess.run([sys.executable, '-c', lookup], env=env, capture_output=True,
                            text=True, check=True).stdout.strip()
    assert Path(prefix) == colcon_install
    exe = Path(prefix) / 'lib/stiction_ros/stiction-sim'
    cfg = Path(prefix) / 'share/stiction_ros/config/concentration_loop.yaml'
    out = tmp_path / 'loop.csv'
    run = subprocess.run([str(exe), str(cfg), '--case', 'no_offset', '--duration', '100',
                          '-o', str(out)], env=env, capture_output=True, text=True,
                         cwd=tmp_path, timeout=120)
    assert run.returncode == 0, run.stderr
    # and the code it ran is the installed copy, not the source tree
    assert out.read_text().startswith('t,sp,op,mv,pv')


def test_installed_node_executable_starts_and_explains_a_bad_parameter(colcon_install):
    site = next((colcon_install / 'lib').glob('python3*/site-packages'))
    env = dict(os.environ, AMENT_PREFIX_PATH=str(colcon_install), PYTHONPATH=str(site))
    exe = colcon_install / 'lib/stiction_ros/valve'
    run = subprocess.run([str(exe), '--ros-args', '-p', 'model:=kanoo'], env=env,
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 2
    assert "model = 'kanoo' is not one of" in run.stderr


def test_the_build_compiles_the_kernels_so_a_node_starts_without_compiling(
        colcon_install, tmp_path):
    site = next((colcon_install / 'lib').glob('python3*/site-packages'))
    assert list((site / 'stiction_ros/kernels/__pycache__').glob('valves.kano_run-*.nbi'))
    # numba reports each cache load and save: the installed valve loads every kernel it
    # uses and compiles (saves) none.
    env = dict(os.environ, AMENT_PREFIX_PATH=str(colcon_install), PYTHONPATH=str(site),
               NUMBA_DEBUG_CACHE='1')
    env.pop('NUMBA_CACHE_DIR', None)
    exe = colcon_install / 'lib/stiction_ros/valve'
    log = tmp_path / 'valve.log'
    with open(log, 'wb') as out:
        proc = subprocess.Popen([str(exe), '--ros-args', '-r', '__ns:=/precompiled'], env=env,
                                stdout=out, stderr=subprocess.STDOUT)
        try:
            deadline = time.monotonic() + 60.0
            while b' at ' not in log.read_bytes() and time.monotonic() < deadline:
                time.sleep(0.1)    # the node logs its model 'at <sample time> s' once started
        finally:
            proc.send_signal(signal.SIGINT)
            proc.wait(30)
    text = log.read_text(errors='replace')
    assert 'data loaded from' in text and str(site) in text, text[-2000:]
    assert 'data saved to' not in text, text[-2000:]
