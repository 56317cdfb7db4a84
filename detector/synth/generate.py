"""``poles synth``: render an annotated dataset in the Roboflow layout, in parallel and reproducibly."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from detector.console import show_progress
from detector.datasets.io import DatasetWriter
from detector.datasets.model import Instance
from detector.datasets.polygons import mask_to_polygon
from detector.parallel import default_workers, ordered_map
from detector.preview import contact_sheet, draw_instances
from detector.synth.backdrops import backdrop_cast, load_backdrop, sample_look
from detector.synth.effects import apply_camera_effects, camera_effects
from detector.synth.floor import floor_of
from detector.synth.readable import misread_bands
from detector.synth.objects import repainted
from detector.synth.render import MIN_BAND_PIXELS, MIN_BAND_SHARE, Frame, PoleTruth, render_scene
from detector.synth.scene import BackdropShot, Scene, SceneConfig, calibration_scene, sample_scene
from detector.synth.walk import simulated_walk, walk_frame_steps, walk_scene
from naoslam.camera import NAO_HFOV_DEG, PinholeCamera
from naoslam.landmarks import CLASSES
from naoslam.sim import PATHS
from detector.formats import stamped

#: Images ``poles synth`` renders unless told.
DEFAULT_SYNTH_IMAGES = 500
#: Thesis split: 70 % train, 20 % test, 10 % valid.
SPLIT_RATIOS = {"train": 0.7, "test": 0.2, "valid": 0.1}
CALIBRATION_RANGES_M = (0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0)
CALIBRATION_ANGLES_DEG = (0.0, -10.0, 10.0, -20.0, 20.0)
#: A landmark with fewer visible pixels than this is too small to annotate (and to learn from).
MIN_LABEL_PIXELS = 15
PREVIEW_IMAGES = 12
#: Renders at most of one frame's scene while a labelled pole's band reads as another colour (each repaints those poles).
MAX_RENDERS = 6


@dataclass(frozen=True)
class SynthJob:
    """What to render: image count, seed, frame size, field of view, and whether these are calibration shots."""

    images: int
    seed: int
    width: int = 640
    height: int = 480
    hfov_deg: float = NAO_HFOV_DEG
    calibration_shots: bool = False
    config: SceneConfig = SceneConfig()
    #: Real frames without poles to draw the objects over (``scan_backdrops``); empty: the modelled room.
    backgrounds: tuple[Path, ...] = ()
    #: Fraction of frames drawn over a backdrop when ``backgrounds`` is given; the rest are fully ray-cast.
    backdrop_share: float = 1.0
    #: Render the first ``images`` frames of this simulated walk (``naoslam.sim.PATHS``, the walk of ``poles slam
    #: --sim`` with this seed) instead of random scenes: a swaying camera, the six poles at their field positions.
    walk: str | None = None

    def __post_init__(self) -> None:
        if self.walk is not None and self.walk not in PATHS:
            raise ValueError(f"--walk {self.walk!r} is not one of {', '.join(PATHS)}")
        if self.walk is not None and (self.calibration_shots or self.backgrounds):
            raise ValueError("--walk renders the walk's own venue: leave out --calibration-shots and --backgrounds")
        if not 0.0 <= self.backdrop_share <= 1.0:
            raise ValueError(f"--backdrop-share {self.backdrop_share} must lie between 0 and 1")
        if not 1.0 <= self.hfov_deg <= 179.0:
            raise ValueError(f"--hfov {self.hfov_deg} must lie between 1 and 179 degrees")

    @property
    def camera(self) -> PinholeCamera:
        return PinholeCamera(self.width, self.height, self.hfov_deg)


@dataclass
class RenderedSample:
    """One encoded image with its labels and per-landmark truth, as a worker returns it."""

    index: int
    jpeg: bytes
    instances: list[Instance]
    truth: list[dict]
    camera: dict
    width: int
    height: int
    backdrop: str | None
    #: How many times misread poles were repainted and the scene rendered again (``draw_frame``).
    repaints: int


def split_names(n: int, seed: int) -> list[str]:
    """Assign ``n`` images to train/test/valid in the thesis's 70/20/10 ratio, shuffled by ``seed``."""
    counts = {split: round(ratio * n) for split, ratio in SPLIT_RATIOS.items()}
    counts["valid"] = n - counts["train"] - counts["test"]
    order = [split for split, count in counts.items() for _ in range(count)]
    return [order[i] for i in np.random.default_rng([seed, 0x5B117]).permutation(n)]


_EFFECTS = None


def render_one(job: SynthJob, index: int) -> RenderedSample:
    """Render image ``index`` of the job; depends only on (job, index), never on the worker."""
    scene, image, labelled, renders = draw_frame(job, index)
    ok, encoded = cv2.imencode(".jpg", cv2.cvtColor(image, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, scene.jpeg_quality])
    instances, truth = [], []
    camera = scene.camera
    size = np.array([camera.width, camera.height], np.float64)
    for pole in labelled:
        polygon = mask_to_polygon(pole.mask)
        if polygon is None:
            continue
        instances.append(Instance(pole.cls, polygon / size))
        truth.append({"cls": pole.cls, "class_id": CLASSES.index(pole.cls), "range_m": round(pole.range_m, 4),
                      "bearing_rad": round(pole.bearing_rad, 5), "visible_fraction": round(pole.visible_fraction, 4),
                      "band_pixels": [list(pole.band_pixels_shown), list(pole.band_pixels_whole)],
                      "partial": pole.partial, "band_divide_centre_px": [round(c, 2) for c in pole.band_divide_px],
                      "band_centre_distance_px": round(pole.band_centre_distance_px, 2),
                      "position_m": [round(c, 4) for c in pole.position_m], "pixels": int(pole.mask.sum())})
    pose = scene.pose
    camera_info = {"x": round(pose.x, 4), "y": round(pose.y, 4), "height_m": round(pose.z, 4), "yaw_rad": round(pose.yaw, 5),
                   "pitch_rad": round(pose.pitch, 5), "roll_rad": round(pose.roll, 5)}
    backdrop = scene.backdrop
    return RenderedSample(index, encoded.tobytes(), instances, truth, camera_info, camera.width, camera.height,
                          backdrop.path.name if backdrop is not None else None, renders - 1)


def draw_frame(job: SynthJob, index: int) -> tuple[Scene, np.ndarray, list[PoleTruth], int]:
    """Frame ``index``: its scene, the finished uint8 RGB image, the poles to label, and how many renders it took.

    A pole whose band reads as another colour in the finished pixels (``readable.misread_bands``) gets fresh paint
    and the same scene is rendered again, up to ``MAX_RENDERS`` renders; a pole still misread after that stays
    unlabelled. Only the misread poles change, so the frames written keep the sampler's camera poses, pole counts,
    backdrops and looks (back light included) instead of favouring the scenes that happen to read well. A walk's
    poles are the same poles in every frame, so a walk is rendered once and a misread pole is left unlabelled. A team's
    own paint (``SceneConfig.team_paint``) is what its poles look like, whatever colour it reads as: never repainted.
    """
    global _EFFECTS
    if _EFFECTS is None:
        _EFFECTS = camera_effects()
    scene = _draw_scene(job, index, np.random.default_rng([job.seed, index]), _pick_backdrop(job, index))
    max_renders = 1 if job.walk else MAX_RENDERS
    for renders in range(1, max_renders + 1):
        frame = _render(job, scene)
        image = apply_camera_effects(_EFFECTS, (frame.image * 255.0 + 0.5).astype(np.uint8), scene.effects_seed)
        labelled = [pole for pole in frame.poles if pole.mask.sum() >= MIN_LABEL_PIXELS and pole.nameable]
        misread = set() if job.config.team_paint else \
            {pole.cylinder for pole in labelled if misread_bands(image, pole.cls, pole.band_masks)}
        if not misread or renders == max_renders:
            break
        rng = np.random.default_rng([job.seed, index, renders])
        for cylinder in sorted(misread):
            scene.cylinders[cylinder] = repainted(scene.cylinders[cylinder], job.config.paint.draw(rng))
    return scene, image, [pole for pole in labelled if pole.cylinder not in misread], renders


def _draw_scene(job: SynthJob, index: int, rng: np.random.Generator, backdrop_path: Path | None) -> Scene:
    """One scene for frame ``index`` drawn from ``rng``: over the backdrop (in a look drawn for it) when one is given."""
    camera = job.camera
    if backdrop_path is not None:
        backdrop = load_backdrop(backdrop_path)
        camera = PinholeCamera(backdrop.shape[1], backdrop.shape[0], job.hfov_deg)
        floor = floor_of(backdrop_path)
        scene = sample_scene(rng, camera, job.config, goal_posts_in_view=False, floor=floor)
        look = sample_look(rng, backdrop, backdrop_cast(backdrop_path), job.config.backlight_share)
        scene.backdrop = BackdropShot(backdrop_path, look)
        return scene
    if job.calibration_shots:
        # Ranges vary fastest, so any number of shots covers every distance.
        range_m = CALIBRATION_RANGES_M[index % len(CALIBRATION_RANGES_M)]
        angle = CALIBRATION_ANGLES_DEG[(index // len(CALIBRATION_RANGES_M)) % len(CALIBRATION_ANGLES_DEG)]
        return calibration_scene(rng, camera, CLASSES[index % len(CLASSES)], range_m, angle, job.config)
    if job.walk:
        return walk_scene(simulated_walk(job.walk, job.seed), walk_frame_steps(job.walk, job.seed)[index], job.seed,
                          camera)
    return sample_scene(rng, camera, job.config)


def _render(job: SynthJob, scene: Scene) -> Frame:
    """The scene ray-cast (before the camera effects), over its backdrop if it has one."""
    if scene.backdrop is None:
        return render_scene(scene, job.config.pole)
    path = scene.backdrop.path
    return render_scene(scene, job.config.pole, backdrop=load_backdrop(path), look=scene.backdrop.look,
                        floor=floor_of(path))


def _pick_backdrop(job: SynthJob, index: int) -> Path | None:
    """The backdrop of frame ``index`` (None: fully ray-cast), from its own random stream so scenes stay comparable."""
    if not job.backgrounds or job.calibration_shots:
        return None
    rng = np.random.default_rng([job.seed, index, 0xBAC6])
    if rng.random() >= job.backdrop_share:
        return None
    return job.backgrounds[int(rng.integers(len(job.backgrounds)))]


def _render_star(args: tuple[SynthJob, int]) -> RenderedSample:
    return render_one(*args)


def generate_dataset(out: str | Path, job: SynthJob, *, workers: int | None = None, preview: bool = False,
                     force: bool = False, progress: bool = True, protect: tuple[Path, ...] = (),
                     split: str | None = None) -> Path:
    """Render ``job.images`` frames into a Roboflow-layout dataset at ``out`` with ``annotations.json``.

    Calibration shots and a walk's frames all go to the ``test`` split; other frames are split 70/20/10
    (train/test/valid), or all go to ``split`` when one is named (a set to evaluate on, a set to train on). ``protect``: folders ``out`` may not overlap (the backgrounds folder: frames with poles
    written into it would be read back as frames without).
    """
    walk_length = len(walk_frame_steps(job.walk, job.seed)) if job.walk else None
    if walk_length is not None and job.images > walk_length:
        raise ValueError(f"--images {job.images}: the {job.walk} walk takes {walk_length} frames - ask for that many "
                         "or fewer")
    kind = "calib" if job.calibration_shots else "walk" if job.walk else "synth"
    splits = [split or "test"] * job.images if kind != "synth" or split else split_names(job.images, job.seed)
    workers = workers or default_workers(job.images)
    annotations = {"classes": list(CLASSES), "generator": _describe(job), "fields": ANNOTATION_FIELDS, "images": {}}
    tiles = []
    with DatasetWriter(out, force=force, protect=protect) as writer:
        results = ordered_map(_render_star, ((job, i) for i in range(job.images)), workers)
        for sample in show_progress(results, "rendering", "img", total=job.images, enabled=progress):
            name = f"{kind}_{sample.index:05d}.jpg"
            writer.add(splits[sample.index], name, sample.jpeg, sample.instances)
            annotations["images"][name] = {"split": splits[sample.index], "width": sample.width,
                                           "height": sample.height, "camera": sample.camera, "backdrop": sample.backdrop,
                                           "repaints": sample.repaints,
                                           "landmarks": sample.truth}
            if preview and len(tiles) < PREVIEW_IMAGES:
                image = cv2.imdecode(np.frombuffer(sample.jpeg, np.uint8), cv2.IMREAD_COLOR)
                tiles.append((draw_instances(image, sample.instances), name))
        writer.write_json("annotations.json", stamped("annotations", annotations))
    if preview and tiles:
        print(f"preview: {contact_sheet(tiles, writer.out / 'preview.png')}")
    return writer.out


def _describe(job: SynthJob) -> dict:
    pole = job.config.pole
    return {"seed": job.seed, "images": job.images, "width": job.width, "height": job.height, "hfov_deg": job.hfov_deg,
            "focal_px": round(job.camera.focal_px, 3), "calibration_shots": job.calibration_shots, "walk": job.walk,
            "backgrounds": len(job.backgrounds), "backdrop_share": job.backdrop_share,
            "nominal_paint_share": job.config.nominal_paint_share, "far_share": job.config.far_share,
            "backlight_share": job.config.backlight_share,
            "team_paint": {letter: [round(c, 4) for c in rgb] for letter, rgb in job.config.team_paint} or None,
            "pole": {"diameter_m": pole.diameter, "band_height_m": pole.band_height, "base_height_m": pole.base_height}}


ANNOTATION_FIELDS = {
    "range_m": "horizontal distance from the camera to the pole axis at the ground",
    "bearing_rad": "direction of the pole from the camera's heading, left positive",
    "visible_fraction": "visible pixels / pixels of the whole unoccluded silhouette (also outside the image)",
    "band_pixels": "visible pixels of the upper and the lower coloured band, then those bands' pixels uncut and "
                   f"unhidden; a pole is labelled only when each band shows {MIN_BAND_PIXELS} pixels or "
                   f"{MIN_BAND_SHARE:.0%} of itself",
    "partial": "true if part of the pole's silhouette lies outside the image",
    "band_divide_centre_px": "projection of the pole-axis point between the two coloured bands, x right, y down",
    "band_centre_distance_px": "pixel distance between the projected centres of the two coloured bands",
    "position_m": "pole base on the field (x, y)",
    "pixels": "visible mask area in pixels",
    "camera": "camera position on the field, height, yaw, pitch (down positive), roll",
    "backdrop": "file name of the real frame the objects were drawn over (null: the modelled room)",
    "repaints": "times this frame's scene was rendered again because a labelled pole's band read as another colour in "
                f"the pixels, with fresh paint on those poles only (at most {MAX_RENDERS - 1}; poles still misread "
                "after that are left unlabelled)",
}
