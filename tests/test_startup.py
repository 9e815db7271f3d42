"""Start-up: `ltc --help`, `ltc info` and `ltc query` import only what they use (issue 11).

scipy, jsonschema, matplotlib, onnxruntime, Pillow/OpenCV and rerun cost 0.05-0.3 s CPU each to
import; none of these commands needs them. The check is on the modules loaded (not on a time), in
a fresh interpreter so that other tests' imports do not count.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from ltc_cli.map.store import save_map
from tests.sample_maps import hand_map

HEAVY = ("scipy", "jsonschema", "matplotlib", "onnxruntime", "PIL", "cv2", "rerun", "sklearn", "threadpoolctl")

_PROBE = """
import json, sys
sys.argv = ["ltc"] + json.loads(sys.argv[1])
from ltc_cli.cli import main
try:
    main()
except SystemExit:
    pass
print(json.dumps(sorted({m.split(".")[0] for m in sys.modules})), file=sys.stderr)
"""


def loaded_packages(args: list[str]) -> set[str]:
    done = subprocess.run([sys.executable, "-c", _PROBE, json.dumps(args)], capture_output=True, text=True, check=True)
    return set(json.loads(done.stderr.strip().splitlines()[-1]))


def test_help_imports_neither_numpy_nor_any_heavy_package():
    mods = loaded_packages(["--help"])
    assert "click" in mods  # the probe ran the command
    assert not mods & {"numpy", "h5py", *HEAVY}, mods & {"numpy", "h5py", *HEAVY}


@pytest.mark.parametrize("command", ["info", "query"])
def test_map_commands_import_h5py_but_no_heavy_package(tmp_path, command):
    path = tmp_path / "m.h5"
    save_map(hand_map(), path)
    mods = loaded_packages([command, str(path)])
    assert "h5py" in mods  # the map was read
    assert not mods & set(HEAVY), mods & set(HEAVY)
