"""A Foxglove app layout for a run's topics (:func:`layout`): the 3D panel in frame ``world``,
plots of each filter's error against its sigma and the PCRB, the NEES, and the events log."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from beacon_sim.io.foxglove_schemas import FRAME


def layout(topics: Sequence[str], filter_names: Sequence[str]) -> dict[str, Any]:
    """A Foxglove app layout (Layouts > Import from file) for a run with these ``topics``:
    a 3D panel in frame ``world`` showing every scene, pose, grid, scan and particle topic;
    Plot panels of each filter's x error against its sigma, the position error against the
    PCRB's sigma, and the NEES; a Log panel on ``/events``. A panel names only topics the
    run has."""
    topics = list(topics)
    three_d: dict[str, Any] = {}
    for t in topics:
        if t.endswith("/stats") or t in ("/events", "/readings/values"):
            continue
        cfg: dict[str, Any] = {"visible": True}
        if t.endswith("/grid"):
            cfg.update({"colorField": "probability", "colorMode": "colormap", "colorMap": "turbo"})
        elif t == "/map":
            cfg.update({"colorField": "occupancy", "colorMode": "colormap", "colorMap": "rainbow"})
        elif t.endswith("/particles"):
            cfg.update({"type": "arrow", "arrowScale": [0.15, 0.03, 0.03]})
        three_d[t] = cfg

    def series(path: str, label: str) -> dict[str, Any]:
        return {"value": path, "enabled": True, "timestampMethod": "receiveTime", "label": label}

    names = [n for n in filter_names if f"/filters/{n}/stats" in topics]
    err_x = [s for n in names for s in (series(f"/filters/{n}/stats.err_x_m", f"{n} error x [m]"),
                                        series(f"/filters/{n}/stats.sigma_x_m", f"{n} sigma x [m]"))]
    pos = [series(f"/filters/{n}/stats.err_pos_m", f"{n} position error [m]") for n in names]
    if "/pcrb/stats" in topics:
        pos.append(series("/pcrb/stats.sigma_pos_m", "PCRB sigma [m]"))
    nees = [series(f"/filters/{n}/stats.nees", f"{n} NEES") for n in names]

    def plot(title: str, paths: list) -> dict[str, Any]:
        return {"title": title, "paths": paths, "showLegend": True, "legendDisplay": "floating",
                "showXAxisLabels": True, "showYAxisLabels": True, "xAxisVal": "timestamp", "isSynced": True}

    return {
        "configById": {
            "3D!beacon": {"followTf": FRAME, "followMode": "follow-none", "topics": three_d,
                          "cameraState": {"perspective": False, "distance": 30, "phi": 0, "thetaOffset": 90,
                                          "targetOffset": [0, 0, 0]}},
            "Plot!error": plot("x error and sigma", err_x),
            "Plot!position": plot("position error and the PCRB", pos),
            "Plot!nees": plot("NEES", nees),
            "Log!events": {"topicToRender": "/events", "minLogLevel": 1, "searchTerms": []},
        },
        "globalVariables": {}, "userNodes": {}, "playbackConfig": {"speed": 1},
        "layout": {"direction": "row", "splitPercentage": 60, "first": "3D!beacon",
                   "second": {"direction": "column", "splitPercentage": 75,
                              "first": {"direction": "column", "splitPercentage": 33,
                                        "first": "Plot!error",
                                        "second": {"direction": "column", "first": "Plot!position",
                                                   "second": "Plot!nees"}},
                              "second": "Log!events"}},
    }

