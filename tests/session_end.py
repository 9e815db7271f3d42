"""The end of a session over a hand-made map, as ``ltc ingest`` ends one (vertex metric,
non-detection policy), for the tests of the end-of-session rules (pruning.py)."""

from ltc_cli import plugins
from ltc_cli.pipeline.mapper import Mapper


def end_session(smap, cfg, session: int = 1):
    """Run ``Mapper.prune_unconfirmed`` of ``session`` over ``smap`` with ``cfg``, as at a session's end."""
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=session)
    m = cfg["maintenance"]
    mapper.prune_unconfirmed(m["min_detections"], -1, "end of session", m["min_detection_share"])
    return smap
