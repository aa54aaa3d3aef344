"""``beacon-sim graph``'s window: a factor graph optimised one solver step per key press.

The world view shows the pose chain (odometry edges), the loop closures, the landmark edges
and the landmarks; the truth (a run's) in black underneath. The edges of largest chi2 are
drawn thick in the warning colour. The panel shows the iteration, the method, chi2 per edge
class before and after the last step, and the worst edges; S shows the sparsity of the
information matrix H, E the marginal covariances (95 % ellipses) at the current nodes.

Keys: N, Space or Right: one step. L: Gauss-Newton / Levenberg-Marquardt. E: ellipses.
S: H's sparsity. R: back to the initial values. Esc or Q: quit.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pygame

from beacon_sim.app import palette
from beacon_sim.app.assets import load_fonts
from beacon_sim.app.framebuffer import choose_framebuffer
from beacon_sim.core.geometry import CHI2_2DOF, covariance_ellipse
from beacon_sim.filters.graph.graph import FactorGraph
from beacon_sim.filters.graph.solver import GraphSolver, Layout, StepReport, marginals, normal_equations

#: How many of the worst edges are highlighted.
WORST = 10
#: Colours of the edge classes (Okabe-Ito).
CLASS_COLOURS = {"odometry": (0, 114, 178), "loop closure": (204, 121, 167), "landmark": (200, 200, 200)}
LANDMARK = (0, 158, 115)
#: Ellipses for at most this many poses (every k-th pose otherwise).
ELLIPSE_POSES = 60


class GraphWindow:
    """The window over a :class:`GraphSolver` (see the module). ``truth``: true poses (n, 3)
    at the graph's pose nodes and true landmarks (m, 2), when the graph is a run's."""

    def __init__(self, graph: FactorGraph, method: str = "gn", size: tuple[int, int] = (1280, 800),
                 truth_poses: np.ndarray | None = None, truth_marks: np.ndarray | None = None,
                 title: str = "", solver_cls: type[GraphSolver] = GraphSolver):
        pygame.display.init()
        pygame.font.init()
        choose_framebuffer(pygame.display.get_driver())
        self.screen = pygame.display.set_mode(size)
        pygame.display.set_caption(f"beacon-sim graph: {title or graph.source}")
        self.fonts = load_fonts(size[1], size[0])
        self.initial = graph
        self.method = method
        self.solver_cls = solver_cls
        self.solver = solver_cls(graph, method)
        self.truth_poses, self.truth_marks = truth_poses, truth_marks
        self.title = title or graph.source
        self.last: StepReport | None = None
        self.step_ms = 0.0
        self.show_sparsity = False
        self.show_ellipses = False
        self.ellipses: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.spy: pygame.Surface | None = None
        self.running = True
        self.message = ""
        w, h = size
        self.panel = pygame.Rect(w - int(0.3 * w), 0, int(0.3 * w), h)
        self.area = pygame.Rect(0, 0, w - self.panel.width, h)
        self._fit()

    # -- the view --------------------------------------------------------------------------
    def _fit(self) -> None:
        g = self.solver.graph
        pts = [g.poses[:, :2], g.landmarks]
        if self.truth_poses is not None:
            pts.append(self.truth_poses[:, :2])
        xy = np.vstack([p for p in pts if p.size])
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        span = np.maximum(hi - lo, 1e-6)
        a = self.area.inflate(-60, -60)
        self.scale = float(min(a.width / span[0], a.height / span[1]))
        self.origin = (lo + hi) / 2.0
        self.centre = np.array(a.center, dtype=float)

    def to_px(self, xy: np.ndarray) -> np.ndarray:
        d = (np.asarray(xy, dtype=float) - self.origin) * self.scale
        return np.stack([self.centre[0] + d[..., 0], self.centre[1] - d[..., 1]], -1)

    # -- actions -------------------------------------------------------------------------
    def step(self) -> None:
        """One solver step; a system the solver cannot solve (a node no edge fixes) is said
        on the panel and the nodes stay where they are."""
        t0 = time.process_time()
        try:
            self.last = self.solver.step()
        except Exception as exc:  # a singular system, or a user's solver (--solver) that raised
            self.message = f"no step: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}"
            return
        self.step_ms = 1e3 * (time.process_time() - t0)
        self.ellipses = None
        if self.show_ellipses:
            self._marginals()

    def toggle_method(self) -> None:
        self.method = "lm" if self.method == "gn" else "gn"
        graph, it = self.solver.graph, self.solver.iteration
        self.solver = self.solver_cls(graph, self.method)
        self.solver.iteration = it
        self.message = f"next steps: {'Levenberg-Marquardt' if self.method == 'lm' else 'Gauss-Newton'}"

    def reset(self) -> None:
        self.solver = self.solver_cls(self.initial, self.method)
        self.last, self.ellipses = None, None
        if self.show_ellipses:
            self._marginals()

    def _marginals(self) -> None:
        g = self.solver.graph
        every = max(g.n_poses // ELLIPSE_POSES, 1)
        idx = np.arange(0, g.n_poses, every)
        try:
            P, L = marginals(g, idx)
        except Exception as exc:  # a singular H (a landmark seen once by bearing only...)
            self.message = f"no marginals: {exc}"
            self.show_ellipses = False
            return
        self.ellipses = (idx, P, L)

    def _sparsity(self) -> pygame.Surface:
        """H's pattern binned into a square image (dark: a non-zero block)."""
        g = self.solver.graph
        layout = Layout(g)
        rows, cols, _, _ = normal_equations(g, layout)
        n = max(layout.size, 1)
        side = min(self.panel.width - 40, 200)
        img = np.full((side, side), 255, dtype=np.uint8)
        r = (rows * side) // n
        c = (cols * side) // n
        img[r, c] = 30
        rgb = np.repeat(img.T[:, :, None], 3, axis=2)
        return pygame.surfarray.make_surface(rgb)

    def handle(self, event: Any) -> None:
        if event.type == pygame.QUIT:
            self.running = False
        elif event.type == pygame.KEYDOWN:
            k = event.key
            if k in (pygame.K_ESCAPE, pygame.K_q):
                self.running = False
            elif k in (pygame.K_n, pygame.K_SPACE, pygame.K_RIGHT):
                self.step()
            elif k == pygame.K_l:
                self.toggle_method()
            elif k == pygame.K_e:
                self.show_ellipses = not self.show_ellipses
                if self.show_ellipses and self.ellipses is None:
                    self._marginals()
            elif k == pygame.K_s:
                self.show_sparsity = not self.show_sparsity
            elif k == pygame.K_r:
                self.reset()

    # -- drawing -------------------------------------------------------------------------
    def draw(self) -> None:
        surf = self.screen
        surf.fill(palette.BACKGROUND)
        g = self.solver.graph
        clip = surf.get_clip()
        surf.set_clip(self.area)
        if self.truth_poses is not None:
            truth = self.to_px(self.truth_poses[:, :2]).tolist()
            pygame.draw.lines(surf, palette.TRUTH_TRAIL, False, truth, 1)
        if self.truth_marks is not None:
            for x, y in self.to_px(self.truth_marks).tolist():
                pygame.draw.rect(surf, palette.BEACON, pygame.Rect(x - 6, y - 6, 12, 12), 2)
        P = self.to_px(g.poses[:, :2])
        L = self.to_px(g.landmarks) if g.n_landmarks else np.zeros((0, 2))
        for es in g.edges:
            colour = CLASS_COLOURS.get(es.label, palette.TEXT_DIM)
            a = P[es.i]
            b = L[es.j] if es.to_landmark else P[es.j]
            if es.label == "odometry":
                continue  # drawn as the chain below
            width = 1
            for (x0, y0), (x1, y1) in zip(a.tolist(), b.tolist(), strict=True):
                pygame.draw.line(surf, colour, (x0, y0), (x1, y1), width)
        for es in g.edges:
            if es.label == "odometry":
                for a, b in zip(P[es.i].tolist(), P[es.j].tolist(), strict=True):
                    pygame.draw.line(surf, CLASS_COLOURS["odometry"], a, b, 2)
        for x, y in L.tolist():
            pygame.draw.rect(surf, LANDMARK, pygame.Rect(x - 4, y - 4, 9, 9))
        if self.ellipses is not None and self.show_ellipses:
            idx, Pc, Lc = self.ellipses
            for k, p in enumerate(idx.tolist()):
                if Pc[k, 0, 0] > 0:
                    pts = self.to_px(covariance_ellipse(g.poses[p, :2], Pc[k, :2, :2], CHI2_2DOF[0.95], 48))
                    pygame.draw.lines(surf, CLASS_COLOURS["odometry"], True, pts.tolist(), 1)
            for k in range(g.n_landmarks):
                pts = self.to_px(covariance_ellipse(g.landmarks[k], Lc[k], CHI2_2DOF[0.95], 48))
                pygame.draw.lines(surf, LANDMARK, True, pts.tolist(), 2)
        for _, label, i, j in g.worst_edges(WORST):
            es_land = label == "landmark"
            a = P[i]
            b = L[j] if es_land else P[j]
            pygame.draw.line(surf, palette.WARN, a.tolist(), b.tolist(), 4)
        surf.set_clip(clip)
        self.draw_panel(surf)
        pygame.display.flip()

    def draw_panel(self, surf: pygame.Surface) -> None:
        r = self.panel
        surf.fill(palette.PANEL, r)
        pygame.draw.line(surf, palette.PANEL_EDGE, r.topleft, r.bottomleft, 3)
        f, small, title = self.fonts["hud"], self.fonts["small"], self.fonts["title"]
        x, y = r.left + 16, 12

        def line(text: str, font: Any = f, colour: Any = palette.TEXT) -> None:
            nonlocal y
            surf.blit(font.render(text, True, colour), (x, y))
            y += font.get_linesize()

        line("graph SLAM", title)
        line(self.title[-34:], small, palette.TEXT_DIM)
        g = self.solver.graph
        line(f"{g.n_poses} poses, {g.n_landmarks} landmarks", small)
        line(f"{g.n_edges} edges", small)
        meth = "Gauss-Newton" if self.method == "gn" else "Levenberg-Marquardt"
        line(f"iteration {self.solver.iteration}  ({meth})")
        now = g.chi2_by_class()
        before = self.last.chi2_before if self.last is not None else None
        y += 6
        line(f"{'chi2':<13}{'before':>11}{'now':>11}", small, palette.TEXT_DIM)
        for label in [*now, "total"]:
            b = (sum(before.values()) if label == "total" else before.get(label)) if before else None
            v = sum(now.values()) if label == "total" else now[label]
            colour = CLASS_COLOURS.get(label, palette.TEXT) if label != "landmark" else palette.TEXT
            line(f"{label:<13}{_num(b):>11}{_num(v):>11}", small, colour)
        if self.last is not None:
            kept = "" if self.last.accepted else "  (refused)"
            line(f"step {self.step_ms:.0f} ms, |dx| {self.last.step_norm:.3g}{kept}", small)
        y += 6
        line(f"worst {WORST} edges (thick, {'orange'}):", small, palette.WARN)
        for c2, label, i, j in g.worst_edges(5):
            line(f"  {label} {i}-{j}: {_num(c2)}", small)
        y += 6
        if self.show_sparsity:
            if self.spy is None:
                self.spy = self._sparsity()
            line("H: non-zero blocks", small, palette.TEXT_DIM)
            surf.blit(self.spy, (x, y))
            pygame.draw.rect(surf, palette.PANEL_EDGE, self.spy.get_rect(topleft=(x, y)), 1)
            y += self.spy.get_height() + 6
        if self.message:
            line(self.message, small, palette.WARN)
        y = max(y, r.bottom - 3 * small.get_linesize() - 8)
        for text in ("N / Space: one step   L: GN / LM", "E: ellipses   S: H's sparsity",
                     "R: initial values   Esc: quit"):
            line(text, small, palette.TEXT_DIM)

    def run(self, frames: int | None = None, steps: int = 0) -> None:
        """Until quit (or ``frames`` frames); ``steps`` solver steps taken first, one a frame."""
        clock = pygame.time.Clock()
        n = 0
        while self.running:
            for event in pygame.event.get():
                self.handle(event)
            if steps > 0:
                self.step()
                steps -= 1
            self.draw()
            n += 1
            if frames is not None and n >= frames and steps <= 0:
                break
            if frames is None:
                clock.tick(30)


def _num(v: float | None) -> str:
    if v is None:
        return "-"
    return f"{v:,.0f}" if abs(v) >= 1000 else f"{v:.2f}"


def show_graph(graph: FactorGraph, method: str = "gn", frames: int | None = None,
               screenshot: str | None = None, steps: int = 0, size: tuple[int, int] = (1280, 800),
               ellipses: bool = False, sparsity: bool = False, truth_poses: np.ndarray | None = None,
               truth_marks: np.ndarray | None = None, title: str = "",
               solver_cls: type[GraphSolver] = GraphSolver) -> int:
    """The window until quit; saves the last frame to ``screenshot``."""
    from beacon_sim.app.display import check_display

    check_display()
    win = GraphWindow(graph, method, size, truth_poses, truth_marks, title, solver_cls)
    win.show_ellipses, win.show_sparsity = ellipses, sparsity
    if ellipses:
        win._marginals()
    try:
        win.run(frames, steps)
        if screenshot:
            pygame.image.save(win.screen, screenshot)
    finally:
        pygame.quit()
    return 0


__all__ = ["GraphWindow", "show_graph"]
