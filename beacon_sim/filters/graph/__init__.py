"""Graph SLAM: the run as a factor graph, solved by Gauss-Newton (docs/smoothing.md).

Poses and landmarks are the nodes; every odometry step, loop closure and landmark reading is
an edge with an error and an information matrix; the solver moves every node at once to
minimise chi2 = sum of e^T Omega e. Read in this order:

- ``se2.py``: poses in the plane, composed and compared (the g2o conventions);
- ``graph.py``: :class:`FactorGraph`, its edge classes (pose-pose, pose-point,
  range-bearing, bearing), each class's errors and Jacobians on arrays, chi2 per class;
- ``solver.py``: one Gauss-Newton or Levenberg-Marquardt step (the normal equations, sparse
  with scipy when it is installed and the graph is large, dense numpy otherwise), the
  marginal covariances of poses and landmarks.

The family stands on the core only; it never imports another family.
"""

from beacon_sim.filters.graph.graph import EDGE_CLASSES, EdgeSet, FactorGraph
from beacon_sim.filters.graph.solver import GraphSolver, StepReport, marginals

__all__ = ["EDGE_CLASSES", "EdgeSet", "FactorGraph", "GraphSolver", "StepReport", "marginals"]
