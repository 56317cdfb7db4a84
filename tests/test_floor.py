"""A backdrop's floor: feet stand on it, the horizon stays above it, and what stands nearer hides composited objects."""
from __future__ import annotations

import math

import cv2
import numpy as np

from detector.synth.backdrops import FEATHER_REACH_PX, frame_cast, sample_look
from detector.synth.floor import FRONT_MARGIN_PX, pitch_range_deg, read_floor
from detector.synth.render import render_scene
from detector.synth.scene import SceneConfig, foot_pixel, sample_scene
from naoslam.camera import PinholeCamera

WIDTH, HEIGHT = 640, 480
FLOOR_TOP = 200
BOX = (slice(120, 420), slice(250, 330))  # a dark cabinet standing on the floor, taller than the wall line, foot at row 419
INSIDE_BOX = (slice(130, 410), slice(260, 320))  # its inside, clear of the floor closing's rounded corners


def _room_frame(seed: int = 0) -> np.ndarray:
    """A wall above row FLOOR_TOP, a green carpet below with a white line across it, a cabinet standing on the carpet."""
    rng = np.random.default_rng(seed)
    image = np.empty((HEIGHT, WIDTH, 3), np.float32)
    image[:FLOOR_TOP] = (0.85, 0.82, 0.7)
    image[FLOOR_TOP:] = (0.15, 0.5, 0.2)
    image[350:356] = (0.95, 0.95, 0.95)  # a field line: lies on the floor, hides nothing
    image[BOX] = (0.3, 0.1, 0.35)
    return np.clip(image + rng.normal(0, 0.015, image.shape), 0, 1).astype(np.float32)


def test_floor_covers_the_carpet_and_its_lines_not_the_wall_or_the_cabinet():
    floor = read_floor(_room_frame())
    assert floor.floor[FLOOR_TOP + 5 :, :200].all() and floor.floor[352, 400]
    assert not floor.floor[: FLOOR_TOP - 5].any() and not floor.floor[INSIDE_BOX].any()
    assert abs(floor.far_edge - FLOOR_TOP) <= 2


def test_the_cabinet_hides_what_stands_behind_it_and_nothing_in_front():
    floor = read_floor(_room_frame())
    behind = floor.in_front_of(foot_row=330.0)
    assert behind[INSIDE_BOX].all()
    assert not behind[:, :240].any() and not behind[:, 340:].any()  # the line and the wall hide nothing
    assert not floor.in_front_of(foot_row=419.0 - FRONT_MARGIN_PX + 1).any()  # the cabinet's own row: not nearer
    assert not floor.in_front_of(foot_row=470.0).any()


def test_feet_stand_on_the_floor_and_the_horizon_stays_above_it():
    floor = read_floor(_room_frame())
    assert floor.stands_at(100, 300) and floor.stands_at(100, 900) and not floor.stands_at(100, 120)
    assert floor.stands_at(290, 300) and not floor.stands_at(290, 150)  # behind the cabinet, but not past the wall
    assert not floor.stands_at(-50, 120) and floor.stands_at(-50, 300)  # beside the frame: the edge column's floor
    camera = PinholeCamera(WIDTH, HEIGHT)
    low, high = pitch_range_deg(floor, camera.focal_px, camera.cy, 0.5, SceneConfig().pitch_deg)
    for pitch in (low, high):
        horizon = camera.cy - camera.focal_px * math.tan(math.radians(pitch))
        assert horizon <= floor.far_edge
    for index in range(20):
        scene = sample_scene(np.random.default_rng([4, index]), camera, goal_posts_in_view=False, floor=floor)
        for cylinder in (c for c in scene.cylinders if c.label is not None):
            u, v = foot_pixel(scene.pose, camera, cylinder.base[0], cylinder.base[1])
            assert floor.stands_at(u, v)


def test_composited_labels_are_exactly_the_visible_pixels_and_hidden_parts_show_the_frame():
    frame = _room_frame()
    floor = read_floor(frame)
    camera = PinholeCamera(WIDTH, HEIGHT)
    hidden_and_shown = 0
    for index in range(30):
        scene = sample_scene(np.random.default_rng([8, index]), camera, goal_posts_in_view=False, floor=floor)
        look = sample_look(np.random.default_rng(index), frame, frame_cast(frame))
        free = render_scene(scene, backdrop=frame, look=look)
        cut = render_scene(scene, backdrop=frame, look=look, floor=floor)
        objects = render_scene(scene, backdrop=np.zeros_like(frame), look=look, floor=floor).image.any(axis=2)
        far = ~cv2.dilate(objects.astype(np.uint8), np.ones((2 * FEATHER_REACH_PX + 1,) * 2, np.uint8)).astype(bool)
        assert np.array_equal(cut.image[far], frame[far])
        free_masks = {(p.cls, p.position_m): p.mask for p in free.poles}
        for pole in cut.poles:
            unoccluded = free_masks[(pole.cls, pole.position_m)]
            foot_row = foot_pixel(scene.pose, camera, *pole.position_m)[1]
            assert np.array_equal(pole.mask, unoccluded & ~floor.in_front_of(foot_row))
            hidden_and_shown += int((unoccluded & ~pole.mask & far).sum())
    assert hidden_and_shown > 0
