"""Simulated luminance camera: renders the simulated world and reads it through the sensor model.

Each pixel of the requested window looks along its pinhole ray (rig.physics.optics);
where the ray hits the front of the sample inside the collimated lamp beam the
scene luminance is L = f_r(ωi, ωo) · E⊥ · cos θi · texture(x, y) · glint(x, y, ωi, ωo),
with ωo the per-pixel direction from that point to the camera; everywhere else it is the
configured ambient (stray-light) luminance. The lamp housing's occlusion of the
view and the camera's shadow are not modelled: the planner excludes those points.
Whatever is rendered passes through the sensor model (rig.simulators.sensor), which
applies the lens's cos⁴ fall-off, PRNU, DSNU and the optional nonlinearity.
"""

from __future__ import annotations

import functools

import numpy as np
import numpy.typing as npt

from rig.config.rigfile import camera_optics
from rig.core.bands import PARALLEL_MIN_PX, shared
from rig.core.errors import DeviceError
from rig.core.values import Frame, Window
from rig.drivers.interfaces import LuminanceCamera
from rig.physics.charuco_board import BoardError, BoardLayout
from rig.physics.geometry import LAMP_DIRECTION_GCS, camera_frame, camera_unit
from rig.physics.optics import CameraOptics, faces_lamp
from rig.simulators.board import board_luminance, lamp_exit_luminance
from rig.simulators.sensor import SensorModel
from rig.simulators.texture import GlintTexture, ValueNoiseTexture
from rig.simulators.world import SimWorld

try:
    from rig.simulators import _view_kernel
except ImportError:            # installed without a C compiler: lit_view runs in numpy
    _view_kernel = None  # type: ignore[assignment]

#: Points of the spot's outline projected to bound the rays traced: their polygon falls short of
#: the outline's image by its sagitta, under 0.3 px for a spot image 4000 px across.
SPOT_OUTLINE_POINTS = 256
#: Pixels added around the outline's image: its sagitta plus pixel centres (+0.5) and rounding.
SPOT_MARGIN_PX = 2
#: Parts of a frame's glint shared between two CPUs (rig.core.bands.shared): enough to even them out.
GLINT_PARTS = 8


def lit_view(optics: CameraOptics, a_rad: float, b_rad: float, box: Window, frame: np.ndarray,
             radius_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The lit sample seen by the pixels of `box` with the camera at arm angles (a, b) and the sample at
    `frame` (sample_frame): which pixels see it (bool (height, width)), where their rays hit it (sample
    coordinates, m, (N, 2)) and the SCS unit vectors from there back to the camera (ωo, (N, 3)).

    The geometry of rig.physics.optics (pixel_rays, intersect_sample_plane, in_beam), computed so that
    only the lit pixels get (N, 3) arrays: the unnormalised ray d = sx·X − sy·Y − f·B of the pixel at
    sensor coordinates (sx, sy) (camera frame [X | Y | B]) projects on any vector q as sx·(X·q) plus a
    term of sy alone, so over the box it is an outer sum of a row and a column term, of which the lit
    pixels are picked; and the hit o + t·d,
    t = −(o·n)/(d·n), needs no normalised d. A ray hits the front when the camera is on the normal's
    side (o·n > 0) and d·n < 0; it is lit when the hit's GCS x² + z² ≤ r² (a negative r lights nothing).
    """
    cam = camera_frame(a_rad, b_rad)
    origin = optics.distance_m * camera_unit(a_rad, b_rad)
    normal = frame[:, 2]
    height = float(origin @ normal)
    if height <= 0 or radius_m < 0:
        return np.zeros((box.height, box.width), bool), np.empty((0, 2)), np.empty((0, 3))
    sx = (box.x0 + 0.5 - optics.width_px / 2 + np.arange(box.width)) * optics.pixel_pitch_m
    sy = (box.y0 + 0.5 - optics.height_px / 2 + np.arange(box.height)) * optics.pixel_pitch_m
    f = optics.focal_length_m
    # d·q = row term + column term, for q = n, GCS X and Z, the SCS axes; then |d|² = sy² + (sx² + f²)
    x, y, back = (np.stack([normal, [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], *frame.T]) @ cam).T
    rows = np.vstack([np.outer(y, -sy) - (f * back)[:, None], np.square(sy)])
    cols = np.vstack([np.outer(x, sx), np.square(sx) + f * f])
    start = origin @ frame[:, :2]
    if _view_kernel is not None:
        lit = np.empty((box.height, box.width), bool)
        xy, wo = np.empty((lit.size, 2)), np.empty((lit.size, 3))
        n = _view_kernel.lit_rays(rows, cols, height, origin[0], origin[2], radius_m ** 2, start[0], start[1],
                                  lit, xy, wo)
        return lit, xy[:n], wo[:n]
    along = [np.add.outer(r, c) for r, c in zip(rows, cols)]            # (height, width) each
    with np.errstate(divide="ignore"):
        t = np.divide(-height, along[0], out=np.full_like(along[0], np.nan), where=along[0] < 0)
    hit_x, hit_z = along[1] * t + origin[0], along[2] * t + origin[2]
    with np.errstate(invalid="ignore"):
        lit = np.square(hit_x) + np.square(hit_z) <= radius_m ** 2     # NaN (no hit) is False
    t_lit = t[lit]
    d_scs = np.stack([a[lit] for a in along[3:6]], axis=1)
    xy = d_scs[:, :2] * t_lit[:, None] + start
    return lit, xy, d_scs / -np.sqrt(along[6][lit])[:, None]


class SimCamera(LuminanceCamera):
    """In-process peer of a calibrated luminance camera looking at a SimWorld."""

    def __init__(self, world: SimWorld):
        cfg = world.config
        self.world = world
        self.sensor = cfg.camera.sensor_info()
        self.optics = camera_optics(cfg)
        self.texture = ValueNoiseTexture.from_config(cfg.simulation)
        self.glint = GlintTexture.from_config(cfg.simulation)
        self.model = SensorModel.from_config(cfg.camera, cfg.simulation, world.rng)
        self._scene_key: tuple[object, ...] | None = None
        self._scene_value: tuple[Window, np.ndarray, np.ndarray] | None = None
        #: What is before the camera: the sample in the lamp's beam (`sample`), a ChArUco board on the holder
        #: under the room's lights, or the empty holder with the lamp's exit beyond (`open`); see `show`.
        self.scene: str = "sample"
        self.board: BoardLayout | None = None

    def show(self, scene: str) -> None:
        """Put `scene` before the camera, as the operator does for `rig calibrate geometry`: `sample`, `open` or
        `board <squares_x> <squares_y> <square_m> <marker_m> <dictionary>` (docs/sim-camera-protocol.md)."""
        kind, *words = scene.split() or [""]
        if kind == "board":
            try:
                self.board = BoardLayout.from_scene(words)
            except BoardError as exc:
                raise DeviceError("camera", f"scene {scene!r}: {exc}") from None
        elif kind not in ("sample", "open") or words:
            raise DeviceError("camera", f"scene {scene!r}: one of 'sample', 'open', 'board <squares_x> "
                                        "<squares_y> <square_m> <marker_m> <dictionary>'")
        self.scene = kind

    def identity(self) -> str:
        return "simulated LMK 98-4 (rig sim)"

    def luminance(self, window: Window, illuminance_normal_lx: float,
                  dtype: npt.DTypeLike = np.float64) -> np.ndarray:
        """Noise-free luminance (cd/m², (height, width)) reaching the sensor at the true (physical) motor
        angles: the scene's, through the filter-wheel filter in the beam (true transmission), if any. The
        sensor reads float32 (half the memory of a full frame to fill and read)."""
        transmission = self.world.transmission()       # of the filter in the beam, if any
        if self.scene != "sample":
            return (self._calibration_scene(window) * transmission).astype(dtype)
        lum = np.full((window.height, window.width), self.world.config.simulation.ambient_cd_m2 * transmission,
                      dtype=dtype)
        scene = self._scene(window)
        if scene is not None:
            box, lit, per_lux = scene
            lum[window.inner(box)][lit] = per_lux * (illuminance_normal_lx * transmission)
        return lum

    def _calibration_scene(self, window: Window) -> np.ndarray:
        """The board or the lamp's exit (rig.simulators.board) at the world's truth."""
        world, geometry = self.world, self.world.config.geometry
        motors = np.radians(world.motor_angles_deg())
        if self.scene == "board":
            assert self.board is not None, "show() sets the board with the scene"
            return board_luminance(self.optics, window, self.board, motors, world.holder_frame(), world.camera_mount)
        return lamp_exit_luminance(self.optics, window, motors, world.camera_mount, geometry.lamp_distance_m,
                                   geometry.spot_diameter_m / 2, world.lamp.relative_output(world.clock.now()))

    def _scene(self, window: Window) -> tuple[Window, np.ndarray, np.ndarray] | None:
        """Where the window sees the lit sample, and its luminance there per lux of E⊥: the box of the
        window traced, the lit pixels in it (bool) and their values; None when nothing is lit.

        Only the pose, the window and the sample change this, not time: it is kept for the last
        (pose, window, sample), so that the exposures and dark frames of one point, and the frames
        of a full-frame point, render the geometry and the texture once.
        """
        world, cfg = self.world, self.world.config
        key = (window, world.motor_angles_deg(), world.brdf_model, tuple(world.brdf_params.items()),
               self.texture, self.glint, cfg.geometry.spot_diameter_m)
        if self._scene_key != key:
            self._scene_key, self._scene_value = key, self._render_scene(window)
        return self._scene_value

    def _render_scene(self, window: Window) -> tuple[Window, np.ndarray, np.ndarray] | None:
        """`_scene` computed: f_r · cos θi · texture · glint on the lit pixels (module docstring).

        Rays are traced only in the part of the window that the spot's outline projects into
        (`_spot_bounds`): a tenth of a full frame, whose unlit rest is ambient anyway.
        """
        world = self.world
        a, b = np.radians(world.motor_angles_deg()[2:])
        frame = world.holder_frame()
        if not faces_lamp(frame[:, 2]):
            return None
        box = self._spot_bounds(window, frame[:, 2], a, b)
        if box is None:
            return None
        lit, xy, wo = lit_view(self.optics, a, b, box, frame, world.config.geometry.spot_diameter_m / 2)
        wi = LAMP_DIRECTION_GCS @ frame
        # The glint, the costliest factor, in parts on another CPU while this one does numpy's part, then helps.
        glint = np.empty(len(xy))

        def glint_part(part: slice) -> None:
            glint[part] = self.glint(xy[part, 0], xy[part, 1], wi, wo[part])
        edges = np.linspace(0, len(xy), (GLINT_PARTS if len(xy) >= PARALLEL_MIN_PX else 1) + 1).astype(int)
        rest = shared([functools.partial(glint_part, slice(i0, i1)) for i0, i1 in zip(edges[:-1], edges[1:])],
                      lambda: world.brdf(wi, wo) * wi[2] * self.texture(xy[:, 0], xy[:, 1]), len(xy))
        return box, lit, rest * glint

    def _spot_bounds(self, window: Window, normal_gcs: np.ndarray, a_rad: float, b_rad: float) -> Window | None:
        """The part of `window` the spot can be seen in: the bounding box of its outline's image
        (SPOT_OUTLINE_POINTS points of the ellipse where the beam cylinder meets the sample plane),
        grown by SPOT_MARGIN_PX; None if that misses the window. The whole window when the outline
        does not project (a point behind the camera, or the sample edge-on to the beam)."""
        optics, radius_m = self.optics, self.world.config.geometry.spot_diameter_m / 2
        phi = np.linspace(0.0, 2 * np.pi, SPOT_OUTLINE_POINTS, endpoint=False)
        x, z = radius_m * np.cos(phi), radius_m * np.sin(phi)
        with np.errstate(divide="ignore", invalid="ignore"):
            outline = np.stack([x, -(normal_gcs[0] * x + normal_gcs[2] * z) / normal_gcs[1], z], axis=1)
            camera = (outline - optics.distance_m * camera_unit(a_rad, b_rad)) @ camera_frame(a_rad, b_rad)
            ahead = -camera[:, 2]                                   # distance in front of the camera
            u = optics.focal_length_m * camera[:, 0] / ahead / optics.pixel_pitch_m + optics.width_px / 2
            v = -optics.focal_length_m * camera[:, 1] / ahead / optics.pixel_pitch_m + optics.height_px / 2
        if not (np.all(ahead > 0) and np.all(np.isfinite(u)) and np.all(np.isfinite(v))):
            return window
        x0 = max(window.x0, int(np.floor(u.min())) - SPOT_MARGIN_PX)
        y0 = max(window.y0, int(np.floor(v.min())) - SPOT_MARGIN_PX)
        x1 = min(window.x0 + window.width, int(np.ceil(u.max())) + SPOT_MARGIN_PX)
        y1 = min(window.y0 + window.height, int(np.ceil(v.max())) + SPOT_MARGIN_PX)
        return Window(x0, y0, x1 - x0, y1 - y0) if x1 > x0 and y1 > y0 else None

    def capture(self, exposure_s: float, window: Window | None = None) -> Frame:
        return self._expose(exposure_s, window, dark=False)

    def capture_dark(self, exposure_s: float, window: Window | None = None) -> Frame:
        return self._expose(exposure_s, window, dark=True)

    def render(self, exposure_s: float, window: Window | None, dark: bool) -> tuple[Frame, float]:
        """Render the scene at mid-exposure and read it through the sensor, without letting time pass:
        the frame and the rig time its exposure + readout take (the caller spends it, so that a served
        camera's client can sleep it on its own clock while its keep-alives run)."""
        full = self.full_window()
        window = full if window is None else window
        try:
            full.inner(window)
        except ValueError as exc:
            raise DeviceError("camera", str(exc)) from None
        if not np.isfinite(exposure_s):
            raise DeviceError("camera", f"exposure time {exposure_s!r} s is not a number")
        t = float(np.clip(exposure_s, self.sensor.min_exposure_s, self.sensor.max_exposure_s))
        with self.world.computing():        # rendering is no rig time: a real frame costs exposure + readout
            start = self.world.clock.now()
            lum = 0.0 if dark else self.luminance(window, self.world.illuminance_normal_lx(start + t / 2), np.float32)
            pixels = self.model.read(self.world.rng, lum, t, window)
        fraction = (window.width * window.height) / (full.width * full.height)
        duration = t + self.world.config.camera.readout_s * fraction
        return Frame(pixels, t, window, dark=dark, meta={"start_s": start}), duration

    def _expose(self, exposure_s: float, window: Window | None, dark: bool) -> Frame:
        """Render, then spend exposure + readout time on the world's clock."""
        frame, duration = self.render(exposure_s, window, dark)
        self.world.clock.sleep(duration)
        return frame


class UniformSourceCamera(SimCamera):
    """The simulated camera looking into a uniform source (an integrating sphere's port filling the field
    of view) of luminance `luminance_cd_m2`: what `rig calibrate camera` measures on the simulated rig. The
    lens's vignetting and the sensor's PRNU, DSNU and nonlinearity still apply (SensorModel)."""

    def __init__(self, world: SimWorld, luminance_cd_m2: float):
        super().__init__(world)
        self.source_cd_m2 = luminance_cd_m2

    def identity(self) -> str:
        return "simulated camera before a uniform source (rig sim)"

    def luminance(self, window: Window, illuminance_normal_lx: float,
                  dtype: npt.DTypeLike = np.float64) -> np.ndarray:
        return np.full((window.height, window.width), self.source_cd_m2, dtype=dtype)
