"""Calibration: fit a converted model's joint and actuator dynamics to the robot's own logs.

``urdf2mjcf calibrate MODEL.xml LOG... -o OUT/`` (:mod:`.command`) chains these modules:

* :mod:`.logs`: a log (CSV) read into typed arrays and resampled onto the model's timestep;
* :mod:`.params`: which parameters are free (``--free``, ``--params FILE``), with bounds,
  and how each is read from and written into a compiled model;
* :mod:`.fit`: the logged commands replayed in MuJoCo (``mujoco.rollout``) and the tracking
  error minimised by bounded least squares, with intervals from the Jacobian;
* :mod:`.report`: the figures and warnings, as ``report.json`` and ``report.html``;
* :mod:`.apply`: identified values written into an MJCF document (``robot.xml``, and
  ``urdf2mjcf SOURCE --calibration FILE`` on every later conversion);
* :mod:`.run`: the chain itself: model and logs read, parameters fitted, files made.

Beside it, :mod:`.against` replays logged runs in a model (``urdf2mjcf verify
--against``) and :mod:`.excite` writes an excitation trajectory (``urdf2mjcf excite``).
"""
