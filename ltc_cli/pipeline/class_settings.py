"""The per-class settings of stages 2-4 as arrays over the map's classes and "other" (index C),
built once per mapper: a stage's rule then reads the value of each object's class by indexing."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ClassSettings:
    """adjoin_share: (C+1,) ``association.partial_adjoin_share`` (0: the fixed gap only);
    container_width: (C+1,) ``association.container_max_width`` (inf: any); outgrow: C+1 entries of
    ``integration.partial_outgrow`` (None: never); fixture: (C+1,) bool ``maintenance.fixture_classes``;
    whole_width: (C+1,) ``modeling.defined_min_width`` (0: any); max_union: (C+1,)
    ``association.max_union_length`` (inf: any); no_adjoin: (C+1,) bool ``association.adjoin_except``;
    round_footprint: (C+1,) bool ``integration.round_footprint``."""

    adjoin_share: np.ndarray
    container_width: np.ndarray
    outgrow: list
    fixture: np.ndarray
    whole_width: np.ndarray
    max_union: np.ndarray
    no_adjoin: np.ndarray
    round_footprint: np.ndarray

    @classmethod
    def from_settings(cls, classes: list[str], config: dict) -> "ClassSettings":
        shares = config["association"].get("partial_adjoin_share") or {}
        widths = config["association"]["container_max_width"] or {}
        outgrow = config["integration"]["partial_outgrow"] or {}
        fixtures = set(config["maintenance"]["fixture_classes"] or [])
        wholes = config["modeling"].get("defined_min_width") or {}
        unions = config["association"]["max_union_length"] or {}
        no_adjoin = set(config["association"]["adjoin_except"] or [])
        rounds = set(config["integration"].get("round_footprint") or [])
        return cls(np.array([float(shares.get(c, 0.0)) for c in classes] + [0.0]),
                   np.array([float(widths.get(c, np.inf)) for c in classes] + [np.inf]),
                   [outgrow.get(c) for c in classes] + [None],
                   np.array([c in fixtures for c in classes] + [False]),
                   np.array([float(wholes.get(c, 0.0)) for c in classes] + [0.0]),
                   np.array([float(unions.get(c, np.inf)) for c in classes] + [np.inf]),
                   np.array([c in no_adjoin for c in classes] + [False]),
                   np.array([c in rounds for c in classes] + [False]))
