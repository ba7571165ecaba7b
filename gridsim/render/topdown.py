"""Top-down RGB rendering with OpenCV: road, lane markings, vehicles, ego, grid inset.

The view is centred ahead of the ego, north up, ``pixels_per_metre`` pixels per metre (fewer
when the set-points drawn would leave the frame). Nothing is ever shown in a window; frames
are numpy arrays ``(height, width, 3)`` uint8 RGB.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from gridsim.frames import world_to_pixel
from gridsim.render.grids import colourise
from gridsim.vehicle.kinematics import box_corners

_BG = (34, 120, 34)  # grass
_ROAD = (90, 90, 90)
_MARK = (235, 235, 235)
#: Vehicles: the ego, replayed traffic, traffic driven by IDM (handed over from replay).
EGO_COLOUR = (230, 30, 30)
TRAFFIC_COLOUR = (40, 90, 220)
IDM_COLOUR = (250, 160, 40)
#: Set-points: the human reference's next ones (rings, drawn first: a plan that matches
#: them fills them), the last commanded (planned) ones (dots); the destination (a diamond).
REFERENCE_COLOUR = (255, 80, 255)
POINTER_OUTLINE = (20, 20, 20)  # behind the arrow to a human out of view, and its label
PLAN_COLOUR = (255, 220, 0)
DESTINATION_COLOUR = (255, 255, 255)
#: The outline of the ego and of the vehicles it touches, on a frame of a collision.
COLLISION_COLOUR = (255, 255, 255)
#: A vehicle's front quarter is drawn in its colour darkened by this share (its heading).
NOSE_SHADE = 0.55
#: Pixel radii of a set-point's dot and of a reference set-point's ring.
DOT_RADIUS, RING_RADIUS = 3, 6
#: The view leads the ego by what it drives in this long [s], at most LEAD_MAX [m].
LEAD_SECONDS, LEAD_MAX = 0.8, 12.0
#: The scales a frame may take, as shares of the view's ``pixels_per_metre``: the largest at
#: which every set-point and the destination lie :data:`ZOOM_MARGIN` pixels inside the frame
#: and clear of the grid inset (a 2.5 s plan at highway speed, or a goal 5 s ahead, would
#: leave an 80 m x 60 m view; a road curving up to the right would pass under the inset).
ZOOM_STEPS, ZOOM_MARGIN = (1.0, 0.75, 0.5, 0.375, 0.25), 24
#: A frame zooms back in only when its points fit with this much more room (points that
#: hover at a step's edge would switch the scale every frame).
ZOOM_BACK = 1.15
#: The ego's outline in the grid inset (the grid's own colours are green, red and black).
INSET_EGO_COLOUR = (255, 255, 255)
#: pixels: the grid inset's distance from the frame's top and right edges
INSET_MARGIN = 8
#: pixels: a collision's mark around a footprint keeps this far outside it
OUTLINE_GAP = 3
#: pixels: the room the arrow to a human out of view keeps from the caption (top), the
#: legends and the scale bar (bottom), the frame's left edge, and the grid inset (right:
#: beside the inset's width and margin), its label included
POINTER_CLEAR_TOP, POINTER_CLEAR_BOTTOM, POINTER_CLEAR_SIDE = 80, 120, 32


@dataclass(frozen=True)
class ViewSpec:
    """The frame [pixels] and its scale: 8 pixels per metre show 80 m x 60 m around the ego,
    the road's lanes wide enough to see (a frame whose set-points or destination lie
    farther zooms out: :data:`ZOOM_STEPS`)."""

    width: int = 640
    height: int = 480
    pixels_per_metre: float = 8.0
    inset_size: int = 160


class TopDownRenderer:
    """Draws :class:`~gridsim.world.World` states as RGB frames."""

    def __init__(self, view: ViewSpec | None = None) -> None:
        self.view = view or ViewSpec()
        #: The scale [pixels per metre] of the last frame drawn (its scale bar's)
        self.scale = self.view.pixels_per_metre

    def _affine(self, center: np.ndarray, k: float) -> np.ndarray:
        v = self.view
        return np.array(
            [[k, 0.0, v.width / 2 - k * center[0]], [0.0, -k, v.height / 2 + k * center[1]]]
        )

    def _px(self, a: np.ndarray, pts: np.ndarray) -> np.ndarray:
        return np.rint((pts @ a[:, :2].T + a[:, 2]) * 16).astype(np.int32)

    def render(
        self,
        world,
        grid: np.ndarray | None = None,
        overlay: list[tuple[np.ndarray, tuple[int, int, int], str]] | None = None,
        rays: np.ndarray | None = None,
        grid_frame: tuple[float, str] | None = None,
        human: np.ndarray | None = None,
        destination: np.ndarray | None = None,
    ) -> np.ndarray:
        """One frame, centred ahead of the ego (:meth:`centre`); each vehicle's front quarter
        darker (its heading). ``grid`` adds an occupancy-grid inset (top right), with the
        ego's outline in it if ``grid_frame`` = ``(cell size [m], orientation)`` says where it
        is; ``overlay`` is a list of ``(points (K, 2) [m, world], RGB colour, "dot" |
        "ring")`` drawn as dots or rings joined by a line, in order (e.g. set-points);
        ``rays`` ``(R, 2)`` world end points are drawn as lines from the ego; ``human`` [m,
        world], where the human is now, gets an arrow at the frame's edge when out of view;
        ``destination`` [m, world] a diamond. The scale is the view's, or smaller where the
        set-points or the destination would leave the frame (:attr:`scale`)."""
        v = self.view
        ego_xy = world.ego[:2]
        centre = self.centre(world)
        shown = [np.asarray(p, float).reshape(-1, 2) for p, _, _ in overlay or []]
        if destination is not None:
            shown.append(np.asarray(destination, float).reshape(1, 2))
        orientation = grid_frame[1] if grid_frame is not None else "north_up"
        self.scale = k = self._zoom(centre, shown, inset=grid is not None, orientation=orientation)
        a = self._affine(centre, k)
        img = np.empty((v.height, v.width, 3), np.uint8)
        img[:] = _BG
        radius = 0.5 * np.hypot(v.width, v.height) / k
        for poly in world.road.drivable_polygons(ego_xy, radius):
            cv2.fillPoly(img, [self._px(a, poly)], _ROAD, cv2.LINE_AA, shift=4)
        for line in world.road.lane_markings(ego_xy, radius):
            cv2.polylines(img, [self._px(a, line)], False, _MARK, 1, cv2.LINE_AA, shift=4)
        f = world.traffic.fleet
        act = np.flatnonzero(f.active)
        boxes = box_corners(f.x[act], f.y[act], f.psi[act], f.length[act], f.width[act])
        noses = _noses(f.x[act], f.y[act], f.psi[act], f.length[act], f.width[act])
        for j, quad, nose in zip(act, boxes, noses, strict=True):
            self._vehicle(img, a, quad, nose, IDM_COLOUR if f.mode[j] else TRAFFIC_COLOUR)
        if rays is not None:
            origin = self._px(a, ego_xy[None])[0]
            for end in self._px(a, rays):
                cv2.line(img, tuple(origin), tuple(end), (255, 255, 0), 1, cv2.LINE_AA, shift=4)
        c = world.ego_center()
        p = world.ego_params
        ego_box = box_corners(c[0], c[1], world.ego[2], p.length, p.width)
        ego_nose = _noses(c[0], c[1], world.ego[2], p.length, p.width)
        self._vehicle(img, a, ego_box, ego_nose, EGO_COLOUR)
        for points, colour, style in overlay or []:  # each a path: a line through its dots
            px = self._px(a, np.asarray(points, float).reshape(-1, 2))
            cv2.polylines(img, [px], False, colour, 1, cv2.LINE_AA, shift=4)
            for q in px:
                if style == "ring":  # dark behind: legible on the road and the lane marks
                    cv2.circle(img, tuple(q), RING_RADIUS * 16, POINTER_OUTLINE, 4, cv2.LINE_AA,
                               shift=4)  # fmt: skip
                    cv2.circle(img, tuple(q), RING_RADIUS * 16, colour, 2, cv2.LINE_AA, shift=4)
                else:
                    cv2.circle(img, tuple(q), DOT_RADIUS * 16, colour, -1, cv2.LINE_AA, shift=4)
        if overlay:  # the ego's edges above its set-points (a standing ego's cover it)
            cv2.polylines(img, [self._px(a, ego_box)], True, EGO_COLOUR, 2, cv2.LINE_AA, shift=4)
        if destination is not None:
            u, v = (np.asarray(destination, float) @ a[:, :2].T + a[:, 2]).round().astype(int)
            for colour, thickness in ((POINTER_OUTLINE, 4), (DESTINATION_COLOUR, 2)):
                cv2.drawMarker(img, (int(u), int(v)), colour, cv2.MARKER_DIAMOND, 14, thickness,
                               cv2.LINE_AA)  # fmt: skip
        hit = [j for j in world.last.contact.vehicles if f.active[j]]
        if hit:  # a collision: the ego and the cars it touches above the set-points, ringed
            for j in hit:
                quad = box_corners(f.x[j], f.y[j], f.psi[j], f.length[j], f.width[j])
                nose = _noses(f.x[j], f.y[j], f.psi[j], f.length[j], f.width[j])
                self._vehicle(img, a, quad, nose, IDM_COLOUR if f.mode[j] else TRAFFIC_COLOUR)
                self._outline(img, a, quad)
            self._vehicle(img, a, ego_box, ego_nose, EGO_COLOUR)
            self._outline(img, a, ego_box)
        if human is not None:
            self._pointer(img, a, np.asarray(human, float))
        if grid is not None:
            self._inset(img, grid, (world, ego_box) if grid_frame else None, grid_frame)
        return img

    def _vehicle(self, img, a, box: np.ndarray, nose: np.ndarray, colour) -> None:
        """A vehicle's footprint ``box`` (4, 2) [m, world] in ``colour``, its ``nose`` (the
        front quarter) darker."""
        cv2.fillConvexPoly(img, self._px(a, box), colour, cv2.LINE_AA, shift=4)
        dark = tuple(int(c * NOSE_SHADE) for c in colour)
        cv2.fillConvexPoly(img, self._px(a, nose), dark, cv2.LINE_AA, shift=4)

    def _outline(self, img, a, box: np.ndarray) -> None:
        """A collision's mark around a footprint ``box`` (4, 2) [m, world]: white on dark, 3
        pixels outside it (at a small scale a mark on its edges covered a car: the ego and
        the car it hit could not be told apart)."""
        centre = box.mean(axis=0)
        axes = [box[1] - box[0], box[3] - box[0]]
        axes = [e / max(np.hypot(*e), 1e-9) for e in axes]
        margin = OUTLINE_GAP / abs(a[0, 0])  # [m]
        grown = box + margin * sum(np.sign((box - centre) @ e)[:, None] * e for e in axes)
        px = self._px(a, grown)
        for colour, thickness in ((POINTER_OUTLINE, 5), (COLLISION_COLOUR, 2)):
            cv2.polylines(img, [px], True, colour, thickness, cv2.LINE_AA, shift=4)

    def _zoom(self, centre: np.ndarray, points: list[np.ndarray], inset: bool = False,
              orientation: str = "north_up") -> float:  # fmt: skip
        """The largest scale of :data:`ZOOM_STEPS` [pixels per metre] at which ``points``
        ``(N, 2)`` [m, world] lie :data:`ZOOM_MARGIN` pixels inside a frame centred on
        ``centre``, clear of the legends a video writes at the bottom left
        (:func:`~gridsim.render.annotations.legend_boxes`) and (``inset``: the frame has the
        grid inset, of a grid in ``orientation``) of the inset (the smallest when none
        does)."""
        from gridsim.render.annotations import legend_boxes  # (it draws with our colours)

        v = self.view
        if not points:
            return v.pixels_per_metre
        off = np.concatenate(points) - centre
        off = off[np.isfinite(off).all(axis=1)]
        if not len(off):
            return v.pixels_per_metre
        # the inset's corner (top right) and its margin, from the frame's centre [pixels]
        corner = (v.width / 2 - v.inset_size - INSET_MARGIN - ZOOM_MARGIN / 2,
                  -(v.height / 2 - v.inset_size - INSET_MARGIN - ZOOM_MARGIN / 2))  # fmt: skip

        # the legends' bands, grown by half the margin, from the frame's centre [pixels]
        half = ZOOM_MARGIN / 2
        bands = [(x0 - half - v.width / 2, y0 - half - v.height / 2, x1 + half - v.width / 2)
                 for x0, y0, x1, _ in legend_boxes(v.height, inset, orientation)]  # fmt: skip

        def fits(k: float, room: float = 1.0) -> bool:
            du, dv = off[:, 0] * room * k, -off[:, 1] * room * k  # pixels right, down
            inside = ((np.abs(du) <= v.width / 2 - ZOOM_MARGIN).all()
                      and (np.abs(dv) <= v.height / 2 - ZOOM_MARGIN).all())  # fmt: skip
            under = any(((du >= x0) & (du <= x1) & (dv >= y0)).any() for x0, y0, x1 in bands)
            return inside and not under and not (
                inset and ((du >= corner[0]) & (dv <= corner[1])).any())  # fmt: skip

        chosen = next((share * v.pixels_per_metre for share in ZOOM_STEPS
                       if fits(share * v.pixels_per_metre)),
                      ZOOM_STEPS[-1] * v.pixels_per_metre)  # fmt: skip
        if chosen > self.scale and not fits(chosen, ZOOM_BACK):
            return self.scale  # (points at a step's edge: no zooming in and out every frame)
        return chosen

    def centre(self, world) -> np.ndarray:
        """The view's centre [m, world]: ahead of the ego by what it drives in
        :data:`LEAD_SECONDS` (at most :data:`LEAD_MAX`): more of the road ahead than
        behind."""
        x, y, psi, speed = world.ego[:4]
        lead = min(max(float(speed), 0.0) * LEAD_SECONDS, LEAD_MAX)
        return np.array([x + lead * np.cos(psi), y + lead * np.sin(psi)])

    def _pointer(self, img: np.ndarray, a: np.ndarray, human: np.ndarray) -> None:
        """An arrow at the frame's edge towards ``human`` [m, world] if it is out of view."""
        h, w = img.shape[:2]
        u, v = human @ a[:, :2].T + a[:, 2]
        if 0 <= u < w and 0 <= v < h:
            return
        # inside the frame's middle, clear of the caption, the legends, the inset and the bar
        left, top = POINTER_CLEAR_SIDE + 8, POINTER_CLEAR_TOP
        right = max(w - self.view.inset_size - INSET_MARGIN - POINTER_CLEAR_SIDE, left + 40)
        bottom = h - POINTER_CLEAR_BOTTOM
        cx, cy = (left + right) / 2, (top + bottom) / 2
        du, dv = u - cx, v - cy
        scale = min((right - cx) / max(abs(du), 1e-9), (bottom - cy) / max(abs(dv), 1e-9))
        tip = (int(cx + du * scale), int(cy + dv * scale))
        tail = (int(cx + du * scale * 0.85), int(cy + dv * scale * 0.85))
        # white on dark: legible over the road, a car or the grass alike
        cv2.arrowedLine(img, tail, tip, POINTER_OUTLINE, 4, cv2.LINE_AA, tipLength=0.5)
        cv2.arrowedLine(img, tail, tip, REFERENCE_COLOUR, 2, cv2.LINE_AA, tipLength=0.5)
        x, y = tail[0] - 20, tail[1] + (17 if dv < 0 else -11)  # the label's baseline
        (tw, th), base = cv2.getTextSize("human", cv2.FONT_HERSHEY_SIMPLEX, 0.4, 1)
        cv2.rectangle(img, (x - 2, y - th - 2), (x + tw + 2, y + base), POINTER_OUTLINE, -1)
        cv2.putText(img, "human", (x, y), cv2.FONT_HERSHEY_SIMPLEX, 0.4, REFERENCE_COLOUR, 1,
                    cv2.LINE_AA)  # fmt: skip

    def _inset(self, img: np.ndarray, grid: np.ndarray, ego=None, grid_frame=None) -> None:
        s = self.view.inset_size
        h, w = grid.shape
        scale = s / max(h, w)
        tile = cv2.resize(
            colourise(grid),
            (max(1, int(w * scale)), max(1, int(h * scale))),
            interpolation=cv2.INTER_NEAREST,
        )
        if ego is not None:  # the ego's outline where the grid has it
            world, box = ego
            to_px = world_to_pixel(world.ego[:2], world.ego[2], h, w, *grid_frame)
            corners = (box @ to_px[:, :2].T + to_px[:, 2] + 0.5) * scale
            cv2.polylines(tile, [np.rint(corners * 16).astype(np.int32)], True, INSET_EGO_COLOUR,
                          1, cv2.LINE_AA, shift=4)  # fmt: skip
        # (a frame smaller than the inset shows its top left part)
        tile = tile[: img.shape[0] - 2 * INSET_MARGIN, : img.shape[1] - 2 * INSET_MARGIN]
        th, tw = tile.shape[:2]
        x0, y0 = img.shape[1] - tw - INSET_MARGIN, INSET_MARGIN
        img[y0 : y0 + th, x0 : x0 + tw] = tile
        cv2.rectangle(img, (x0 - 1, y0 - 1), (x0 + tw, y0 + th), (255, 255, 255), 1)


def _noses(x, y, psi, length, width) -> np.ndarray:
    """The front quarters of footprints centred at ``(x, y)`` [m] heading ``psi`` [rad]
    (arrays or scalars): boxes ``(..., 4, 2)`` as :func:`box_corners` gives."""
    shift = 0.375 * np.asarray(length, float)
    return box_corners(x + shift * np.cos(psi), y + shift * np.sin(psi), psi,
                       0.25 * np.asarray(length, float), width)  # fmt: skip
