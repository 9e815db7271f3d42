"""A deterministic synthetic house, driven through by a robot, written as ``ltc-recording/1`` folders.

``simulate(outdir, scene, laps, seed)`` builds a house of rooms (walls with doorways, floors) with
furniture of COCO classes, each object made of a few boxes (furniture.py) so that masks and depth
see the background through the gaps. A robot follows the same path in every lap (path.py): in each
room it drives a small loop around the room's free middle with the camera (1.0 m high, pitched ~12
degrees down) looking outwards at the furniture along the walls, so every object is seen from
several places and often only in part; it goes from room to room through the doorways. Between laps
some objects are moved (same id, new pose), some removed and some added (new ids) (changes.py).

Per lap folder (``OUTDIR/lap1``, ``OUTDIR/lap2``, ...): recording.yaml, poses.txt (T_world_camera,
OpenCV camera axes, world z up), rgb/<id>.png, depth/<id>.png (uint16, millimetres, 0 = no reading),
annotations/<id>.png (uint16 ground-truth object ids of the visible surface, 0 = none),
detections/<id>.json (a noisy instance-segmentation detector), ground_truth.json (the objects
present in the lap, how much of each was seen, and the changes since the previous lap).

The modules, in the order a frame goes through them: scene.py and house.py (rooms, placement),
path.py (the robot's poses), raycast.py (exact ray casting with a z-buffer: depth, instance and
shading images), sensor.py (depth noise and quantisation, colour noise), detector.py (the recorded
detector's misses, confusions, bleeding masks, splits and false positives), laps.py (the lap loop),
written by ltc_cli.recordings.writer. Everything random is drawn from numpy Generators seeded by
(seed, lap, frame), so a seed gives byte-identical files.

Profiles (options.PROFILES): ``benign`` (the default of :func:`simulate`) is the simulator above;
``realistic`` (the default of ``ltc simulate``) adds the failure modes of real data, each an option
of its own (docs/simulator.md): a localiser's pose drift in poses.txt (drift.py), per-class,
angle-dependent and view-correlated misses, systematic mislabels and CNN-like masks (views.py),
recurring phantoms (phantoms.py), people walking through (people.py), depth holes and flying pixels
(sensor.py) and sizes varying within a class (house.py); extras.py gathers them per lap.
"""

from ltc_cli.tools.simulate.house import House
from ltc_cli.tools.simulate.laps import OutputExistsError, simulate
from ltc_cli.tools.simulate.options import CLASSES, CONFUSABLE, DEFAULTS, PROFILES, SCENES
from ltc_cli.tools.simulate.path import camera_path
from ltc_cli.tools.simulate.raycast import Renderer

__all__ = ["CLASSES", "CONFUSABLE", "DEFAULTS", "PROFILES", "SCENES", "House", "OutputExistsError", "Renderer",
           "camera_path", "simulate"]
