"""The type of the settings every part reads: one nested mapping, built by :mod:`ltc_cli.config`
from defaults.yaml, the user's ``--config`` and ``--set``, and checked against config.schema.json.

The sections are ``TypedDict``s, so a type checker knows each key and its type while the code reads
``settings["maintenance"]["v_other"]`` as before; a test keeps these keys equal to the schema's.
What each setting means, and why its default, is written next to it in defaults.yaml.
"""

from __future__ import annotations

from typing import Union, Optional, TypedDict


class ModelingSettings(TypedDict):
    thin_max_iterations: int
    thin_fraction: float
    max_points: int
    max_detections: int
    compensate_thinning: bool
    scale_pixels: bool
    min_depth: float
    max_depth: float
    edge_jump: Optional[float]
    picture_flatness: Optional[float]
    picture_depth_noise: Optional[float]
    picture_wall_share: Optional[float]
    picture_object_share: Optional[float]
    picture_min_views: int
    min_depth_share: Optional[float]
    min_mask_explained: Optional[float]
    clustering: str
    stack_gap: Optional[float]
    pixel_weights: Union[bool, list[str]]
    eps: float
    min_samples: int
    min_extent: float
    thin_extent: float
    class_depth: dict[str, float]
    taller_than: dict[str, dict]
    wider_than: dict[str, dict]
    depth_noise: Union[float, str, None]  # a number, None or "auto"
    narrower_than: dict[str, dict]
    higher_than: dict[str, dict]
    top_under: dict[str, dict]
    defined_min_width: dict[str, float]
    max_depth_ratio: Optional[float]
    max_short_side: dict[str, float]
    max_long_side: dict[str, float]
    floor_classes: list[str]
    ground_max_gap: float
    floor_min_top: Optional[float]
    border: int
    occlusion_tolerance: float
    occlusion_window: int


class AssociationSettings(TypedDict):
    metric: str
    threshold_same_class: float
    threshold_other_class: float
    other_class_scale: Optional[float]
    same_class_scale: Optional[float]
    other_class_height_ratio: Optional[float]
    other_class_min_overlap: Optional[float]
    defined_min_overlap: Optional[float]
    seen_apart_gap: Optional[float]
    seen_apart_share: float
    max_union_length: dict[str, float]
    bound_merged_length: bool
    min_visible_pairs: int
    containment: Optional[float]
    containment_other_class: Optional[float]
    other_class_volume_ratio: Optional[float]
    partial_adjoin_gap: Optional[float]
    adjoin_max_turn: dict[str, float]
    adjoin_except: list[str]
    partial_adjoin_share: Optional[dict[str, float]]
    adjoin_same_frame: bool
    merge_other_class_iou: Optional[float]
    merge_adjoining: bool
    merge_partial_defined_gap: Optional[float]
    merge_partial_defined_volume: float
    stand_gap: Optional[float]
    merge_min_overlap: Optional[float]
    established_apart: bool
    defined_apart_detections: Optional[int]
    labels_apart: bool
    tentative_reshapes: bool
    one_view_reshapes: bool
    stand_margin: float
    stand_low: Optional[float]
    stand_centred: Optional[float]
    stand_within: Optional[float]
    stand_within_floor: Optional[float]
    stand_inside_parts: bool
    stand_confirmed: bool
    merge_part_under: bool
    merge_recheck: bool
    part_label_share: Optional[float]
    container_max_width: Optional[dict[str, float]]
    merge_containment: Optional[float]
    merge_other_class_evidence: Optional[float]
    merge_current_box: bool
    merge_id_by_label: bool
    merge: bool


class IntegrationSettings(TypedDict):
    free_space_step: Optional[float]
    free_space_tolerance: float
    free_space_max_share: float
    erosion: float
    round_footprint: list[str]
    max_weight: Optional[float]
    unassigned_score: str
    relabel_weight: str
    stale_box_weight: Optional[float]
    stale_label_weight: Optional[float]
    stale_partial_moves: Union[bool, str]
    defined_part_volume: Optional[float]
    partial_outgrow: dict[str, float | None] | None
    partial_outgrow_turn: Optional[float]


class MaintenanceSettings(TypedDict):
    policy: str
    v_other: float
    v_other_per_class: dict[str, float]
    learn_detection_rate: bool
    nondet_min_move: Optional[float]
    nondet_min_turn: Optional[float]
    seen_empty_share: Optional[float]
    v_other_seen_empty: Optional[float]
    rate_prior: float
    rate_prior_views: float
    rate_score: float
    rate_margin: float
    min_visible_pixels: float
    min_visible_fraction: Optional[float]
    min_pixels_floor: float
    min_visible_share: float
    through_visible_share: float
    min_detections: int
    min_detection_share: Optional[float]
    min_detection_views: Optional[int]
    confirm_across_sessions: bool
    confirm_across_views: bool
    return_after_misses: bool
    reidentify_margin: Optional[float]
    earlier_overlap_iou: Optional[float]
    earlier_small_overlap_iou: Optional[float]
    session_overlap_iou: Optional[float]
    confirm_min_move: Optional[float]
    confirm_min_turn: Optional[float]
    tentative_until_end: bool
    absent_after_views: Optional[int]
    absent_quiet_sessions: Optional[int]
    absent_quiet_views: Optional[int]
    fixture_classes: Optional[list[str]]
    fixture_existence: bool
    absent_through_views: Optional[int]
    absent_through_share: float
    through_margin: float
    nondet_through_share: Optional[float]
    nondet_through_holes: bool
    absent_holes_share: Optional[float]
    occupied_margin: Optional[float]
    occupied_lift: float
    occupied_share: float
    occupied_max_width: float
    spare_frames: Optional[int]
    hidden_by_whole_box: Union[bool, str]
    hide_needs_depth: Union[bool, str]
    ray_step: int
    depth_tolerance: float


class FrameSettings(TypedDict):
    still_move: Optional[float]
    still_turn: Optional[float]


class IndexSettings(TypedDict):
    cell_size: float


class DetectorSettings(TypedDict):
    name: str
    options: dict
    save_to: Optional[str]  # a folder for the detections, as `recorded` reads them (recordings/saved_detections.py)


class MapSettings(TypedDict):
    classes: Optional[list[str]]
    moving_classes: list[str]


class Settings(TypedDict):
    modeling: ModelingSettings
    association: AssociationSettings
    integration: IntegrationSettings
    maintenance: MaintenanceSettings
    frames: FrameSettings
    index: IndexSettings
    detector: DetectorSettings
    map: MapSettings
