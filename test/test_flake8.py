# Copyright 2017 Open Source Robotics Foundation, Inc.
# Licensed under the Apache License, Version 2.0: the reference test of ROS 2 Python packages.
"""Run ament_flake8 with the ROS 2 configuration over the package."""

from ament_flake8.main import main_with_errors
import pytest


@pytest.mark.flake8
@pytest.mark.linter
@pytest.mark.slow
def test_flake8():
    rc, errors = main_with_errors(argv=[])
    assert rc == 0, 'Found %d code style errors / warnings:\n' % len(errors) + '\n'.join(errors)
