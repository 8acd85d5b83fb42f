"""Offline segmenter on synthetic images: colour words pick pixels, components are instances, shape words rank."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from pipeline.perception.offline_segmenter import OfflineSegmenter, parse_phrase
from pipeline.perception.segmenter import SegmentationError

TABLE = (173, 133, 94)  # the sim table's rendered colour


def scene() -> np.ndarray:
    img = np.full((120, 160, 3), TABLE, np.uint8)
    cv2.rectangle(img, (20, 30), (40, 50), (200, 30, 25), -1)  # red square
    cv2.circle(img, (100, 40), 12, (30, 60, 200), -1)  # blue disc
    cv2.rectangle(img, (60, 80), (70, 110), (40, 160, 50), -1)  # green upright bar (a standing cylinder)
    cv2.rectangle(img, (0, 100), (15, 119), (200, 30, 25), -1)  # red region touching the border
    return img


def test_colour_finds_each_object_once_and_ignores_border_regions():
    img = scene()
    seg = OfflineSegmenter()
    red = seg.segment(img, "the red block")
    assert len(red) == 1 and red[0].box == (20, 30, 40, 50) and red[0].area_px == 21 * 21
    blue = seg.segment(img, "blue")
    assert len(blue) == 1 and abs(blue[0].centroid_uv[0] - 100) < 1
    assert seg.segment(img, "yellow block") == []


def test_shape_word_alone_picks_the_matching_silhouette():
    found = OfflineSegmenter().segment(scene(), "the cylinder")
    assert found and found[0].label.startswith("green")


def test_two_same_coloured_objects_are_two_detections():
    img = scene()
    cv2.rectangle(img, (120, 70), (140, 90), (200, 30, 25), -1)
    assert len(OfflineSegmenter().segment(img, "red block")) == 2


def test_phrases_are_validated():
    assert parse_phrase("the grey cube").colour == "gray" and parse_phrase("the grey cube").shape == "box"
    with pytest.raises(SegmentationError, match="unknown word 'gizmo'"):
        parse_phrase("red gizmo")
    with pytest.raises(SegmentationError, match="no colour or shape"):
        parse_phrase("the")
    with pytest.raises(ValueError, match="uint8"):
        OfflineSegmenter().segment(np.zeros((10, 10)), "red block")
