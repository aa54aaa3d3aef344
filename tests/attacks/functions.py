"""A filter written as module-level functions, as the course's slides ask ("use functions"):
``init(ctx)``, ``reset``, ``predict``, ``update``, ``estimate``. Here they drive the built-in
EKF, so its grade must equal the class form's."""

from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter

ekf = None


def init(ctx):
    global ekf
    ekf = ExtendedKalmanFilter(ctx)


def reset(initial):
    ekf.reset(initial)


def predict(control, dt):
    ekf.predict(control, dt)


def update(measurements):
    ekf.update(measurements)


def estimate():
    return ekf.estimate()
