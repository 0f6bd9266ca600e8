"""The viewer's page: meshcat's own, with a title, a legend and a time readout.

Pure text: :func:`page_html` takes meshcat's ``index.html`` and returns it with
the robot's name as the title, a small overlay naming what is drawn (the arm,
the ghost at the target, the path line, each in its colour) and the animation's
time, read from meshcat's animator on every frame.
"""

from __future__ import annotations

import html
import json
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rrt_pin.viewer.drawing import RobotDrawing

__all__ = ["LegendEntry", "meshcat_index", "page_html", "drawing_legend"]


@dataclass(frozen=True)
class LegendEntry:
    """One line of the legend.

    Attributes:
        label: what it is ("arm", "target qf (ghost)", "path of link3 (C3)").
        colour: a CSS colour (or gradient) of its swatch.
        style: ``solid``, ``ghost`` (translucent) or ``line``.
    """

    label: str
    colour: str
    style: str = "solid"


_OVERLAY_CSS = """
#rrt-pin-overlay {
    position: absolute; top: 8px; left: 8px; z-index: 10; pointer-events: none;
    font: 13px/1.45 system-ui, sans-serif; color: #222;
    background: rgba(255, 255, 255, 0.82); border-radius: 6px; padding: 8px 10px;
}
#rrt-pin-overlay h1 { font-size: 14px; margin: 0 0 4px 0; }
#rrt-pin-overlay .swatch {
    display: inline-block; width: 14px; height: 10px; margin-right: 6px; vertical-align: middle;
}
#rrt-pin-overlay .line { height: 3px; }
#rrt-pin-overlay .ghost { opacity: 0.35; }
#rrt-pin-time { font-variant-numeric: tabular-nums; margin-top: 4px; }
"""

# The time readout: meshcat's animator keeps a THREE.AnimationMixer whose time runs
# on (and loops); the clip's duration is the longest track's.
_TIME_JS = """
(function () {
    const out = document.getElementById("rrt-pin-time");
    function tick() {
        try {
            const a = viewer.animator;
            const clip = a.actions.length ? a.actions[0].getClip().duration : 0;
            const t = a.actions.length ? a.actions[0].time : 0;  // the clip's own time
            out.textContent = "t = " + t.toFixed(2) + " s" + (clip > 0 ? " of " + clip.toFixed(2) + " s" : "");
        } catch (e) {
            out.textContent = "";
        }
        requestAnimationFrame(tick);
    }
    requestAnimationFrame(tick);
})();
"""


def page_html(index: str, title: str, legend: list[LegendEntry]) -> str:
    """Meshcat's ``index`` page with ``title``, the ``legend`` overlay and a time readout."""
    rows = "".join(
        f'<div><span class="swatch {html.escape(e.style)}" '
        f'style="background:{html.escape(e.colour)}"></span>{html.escape(e.label)}</div>'
        for e in legend
    )
    overlay = (
        f'<div id="rrt-pin-overlay"><h1>{html.escape(title)}</h1>{rows}'
        '<div id="rrt-pin-time"></div></div>'
    )
    page = index.replace("<title>MeshCat</title>", f"<title>{html.escape(title)}</title>", 1)
    page = page.replace("</head>", f"<style>{_OVERLAY_CSS}</style></head>", 1)
    page = page.replace("<body>", f"<body>{overlay}", 1)
    page = page.replace("</body>", f"<script>{_TIME_JS}</script></body>", 1)
    # The title as data too, for tools that read it without parsing HTML.
    page = page.replace(
        "</head>", f'<meta name="rrt-pin-title" content={json.dumps(title)}></head>', 1
    )
    return page


def _css(rgb: tuple[float, ...]) -> str:
    r, g, b = (min(255, max(0, round(255 * c))) for c in rgb[:3])
    return f"#{r:02x}{g:02x}{b:02x}"


def drawing_legend(drawing: RobotDrawing, ghost: bool = True) -> list[LegendEntry]:
    """What ``scene`` draws, in its colours: the arm, the ghost at the target, the path line."""
    from rrt_pin.viewer.meshcat_scene import PATH_COLOUR

    colours = list(dict.fromkeys(_css(shape.rgba) for shape in drawing.shapes))[:4] or ["#888"]
    colour = colours[0] if len(colours) == 1 else f"linear-gradient(90deg, {', '.join(colours)})"
    out = [LegendEntry("arm (moving)", colour)]
    if ghost and drawing.ghost:
        out.append(LegendEntry("target qf (translucent ghost)", colour, "ghost"))
    if len(drawing.path) > 1:
        out.append(LegendEntry(f"path of {drawing.path_frame}", f"#{PATH_COLOUR:06x}", "line"))
    return out


def meshcat_index() -> str:
    """Meshcat's own ``index.html``."""
    import os

    from rrt_pin.viewer._deps import import_meshcat

    meshcat = import_meshcat()
    path = os.path.join(meshcat.viewer_assets_path(), "dist", "index.html")
    with open(path, encoding="utf-8") as fh:
        return fh.read()
