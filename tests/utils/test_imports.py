"""utils.imports.require_package: the module, or an ImportError that names the pip extra to install."""

import json
import sys

import pytest

from lerobot_unidextok.utils.imports import require_package


def test_an_installed_package_is_returned():
    assert require_package("json", "none", purpose="reading JSON") is json


def test_a_missing_package_names_its_extra_and_the_purpose(monkeypatch):
    monkeypatch.setitem(sys.modules, "rosbags", None)  # import fails as if not installed
    with pytest.raises(
        ImportError,
        match=r"^reading ROS bags needs rosbags: pip install 'lerobot_policy_unidextok\[ros\]' \(pure Python\)$",
    ) as err:
        require_package("rosbags", "ros", purpose="reading ROS bags", hint=" (pure Python)")
    assert isinstance(err.value.__cause__, ImportError)  # the original import error stays attached
