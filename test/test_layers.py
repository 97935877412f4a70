"""
The package's shape, read from its own import statements (README, "Architecture").

Each top-level part of ``stiction_ros`` sits on a layer and may import only
from layers below it; parts on one layer do not import each other.  Imports
inside functions count as much as those at the top of a module: a lazy import
is still a dependency.  These tests fail on the first import that points up
or sideways, naming the module and the line.
"""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / 'stiction_ros'

# Lowest first.  The five root modules are the floor everything stands on.
LAYERS = (
    ('_blas', '_jit', '_threads', 'errors', 'resources'),
    ('kernels',),
    ('models', 'bag'),
    ('sim',),
    ('analysis',),
    ('study', 'viz'),
    ('app',),
    ('nodes',),
    ('cli',),
)
LEVEL = {part: level for level, parts in enumerate(LAYERS) for part in parts}
MAX_ROOT_MODULES = 6
MAX_LINES = 500


def _modules():
    return sorted(p for p in PACKAGE.rglob('*.py') if '__pycache__' not in p.parts)


def _part(path: Path) -> str:
    rel = path.relative_to(PACKAGE)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def _imports(path: Path):
    """Yield (line, imported dotted name) for every stiction_ros import in ``path``."""
    rel = path.relative_to(PACKAGE.parent).with_suffix('')
    here = list(rel.parts[:-1])
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here[:len(here) - node.level + 1]
                name = '.'.join(base + ([node.module] if node.module else []))
            else:
                name = node.module or ''
            yield node.lineno, name
            # 'from stiction_ros import models' imports the part 'models'.
            if name == 'stiction_ros':
                for alias in node.names:
                    yield node.lineno, f'stiction_ros.{alias.name}'


def _target_part(name: str):
    parts = name.split('.')
    if parts[0] != 'stiction_ros' or len(parts) < 2:
        return None
    return parts[1]


def test_every_part_has_a_layer():
    parts = {_part(p) for p in _modules()} - {'__init__'}
    assert parts <= set(LEVEL), f'parts without a layer in LAYERS: {sorted(parts - set(LEVEL))}'


def test_imports_point_down_the_layers():
    wrong = []
    for path in _modules():
        src = _part(path)
        if src == '__init__':
            continue
        for line, name in _imports(path):
            dst = _target_part(name)
            if dst is None or dst == src or dst == '__init__' or dst not in LEVEL:
                continue
            if LEVEL[dst] >= LEVEL[src]:
                wrong.append(f'{path.relative_to(PACKAGE.parent)}:{line} ({src}, layer '
                             f'{LEVEL[src]}) imports {name} ({dst}, layer {LEVEL[dst]})')
    assert not wrong, 'imports that point up or sideways:\n' + '\n'.join(wrong)


def test_the_chosen_layers_forbid_what_the_architecture_forbids():
    # The rules the README states, checked against the table itself so that a
    # later edit of LAYERS cannot quietly allow them.
    for low in ('kernels', 'models', 'bag'):
        for high in ('analysis', 'cli', 'nodes', 'app'):
            assert LEVEL[low] < LEVEL[high]
    assert max(LEVEL.values()) == LEVEL['cli'], 'nothing may import cli'


@pytest.mark.parametrize('library, allowed', [
    ('numba', {'_jit'}),
    ('matplotlib', {'viz', 'study'}),
    ('rclpy', {'nodes', 'cli'}),
])
def test_heavy_libraries_are_imported_in_their_own_parts_only(library, allowed):
    wrong = [f'{p.relative_to(PACKAGE.parent)}:{line}' for p in _modules()
             for line, name in _imports(p)
             if name.split('.')[0] == library and _part(p) not in allowed]
    assert not wrong, f'{library} imported outside {sorted(allowed)}: {wrong}'


@pytest.mark.parametrize('library, modules', [
    ('torch', {'analysis/detection/cnn_train.py'}),
    ('sklearn', {'analysis/detection/train.py', 'cli/detector.py'}),
])
def test_training_libraries_stay_in_the_training_modules(library, modules):
    # The analyzer runs without PyTorch and scikit-learn: only make cnn and
    # make detector (and the tests) may import them.
    wrong = [f'{p.relative_to(PACKAGE.parent)}:{line}' for p in _modules()
             for line, name in _imports(p)
             if name.split('.')[0] == library
             and p.relative_to(PACKAGE).as_posix() not in modules]
    assert not wrong, f'{library} imported outside {sorted(modules)}: {wrong}'


def test_kernels_import_numpy_math_and_jit_only():
    allowed = {'numpy', 'math', 'stiction_ros._jit', 'stiction_ros.kernels'}
    wrong = []
    for path in (PACKAGE / 'kernels').rglob('*.py'):
        for line, name in _imports(path):
            if not any(name == a or name.startswith(a + '.') for a in allowed):
                wrong.append(f'{path.name}:{line} imports {name}')
    assert not wrong, wrong


def test_the_root_holds_few_modules_and_no_module_is_long():
    root = sorted(p.name for p in PACKAGE.glob('*.py'))
    assert len(root) <= MAX_ROOT_MODULES, root
    long = {str(p.relative_to(PACKAGE)): n for p in _modules()
            if (n := len(p.read_text(encoding='utf-8').splitlines())) > MAX_LINES}
    assert not long, f'modules over {MAX_LINES} lines: {long}'


def test_the_checker_sees_an_upward_import(tmp_path):
    # The check itself must be able to fail: an import of analysis from a
    # kernel is found, a relative one included.
    bad = tmp_path / 'stiction_ros' / 'kernels' / 'bad.py'
    bad.parent.mkdir(parents=True)
    bad.write_text('from ..analysis import pipeline\nimport stiction_ros.cli.analyze\n')
    global PACKAGE
    saved, PACKAGE = PACKAGE, tmp_path / 'stiction_ros'
    try:
        found = [(_part(bad), _target_part(n)) for _, n in _imports(bad)]
    finally:
        PACKAGE = saved
    assert ('kernels', 'analysis') in found and ('kernels', 'cli') in found
