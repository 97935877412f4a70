"""
Where the package's data files are: the source tree or an ament install.

In a colcon/ament install, config files live in ``share/stiction_ros/config``;
in the source tree (venv editable install) next to the package.
"""

from pathlib import Path


def config_dir() -> Path:
    """Return the directory holding the shipped YAML files."""
    src = Path(__file__).resolve().parents[1] / 'config'
    if src.is_dir():
        return src
    try:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory('stiction_ros')) / 'config'
    except (ImportError, LookupError, OSError):
        # OSError: no AMENT_PREFIX_PATH at all (no workspace sourced).
        raise FileNotFoundError('cannot find the stiction_ros config directory') from None


def config_file(name: str) -> Path:
    """Return the path of a shipped config file by name."""
    return config_dir() / name
