"""Drive the MIRA3D rovers of a built facility and measure how far the odometry drifts.

The rovers' runner reads a built bundle: ``facility.json`` and the ``scene.xml`` it
names (and a plan a user passes), whose components with wheel roles
(``facility/robots/mira3d_rover/config/roles.yaml``, with each rover's prefix added by
make-facility) are the rovers. It commands
them only through their actuators: wheel velocity servos (rad/s) and the arm's
position servos (rad), one step of MuJoCo at a time, every rover at once.

Odometry is what the real rover could know, integrated after every step:

* **wheel odometry**: differential drive from the wheel joint velocity sensors,
  the wheel radius and the track, on the plane: ``v = r (wl + wr) / 2``,
  ``yaw rate = r (wr - wl) / track`` (each side the mean of its two wheels);
* **wheel + IMU odometry**: the same wheel speed along the rover's x axis, turned
  into the world by the IMU's orientation (its ``framequat`` sensor: what an
  attitude filter gives), so it follows slopes and the gyro, not the scrubbing
  wheels, gives the heading.

Both are compared with the true pose of the rover's base body, which shows the
wheel slip of a skid-steer rover: turning in place, its wheels scrub sideways,
and the wheels' yaw estimate is far too large (the MIRA3D paper: "odometry data
... differ from reality very fast").

Tasks (``Straight``, ``Turn``, ``Hold``) are small closed loops on the odometry, as a
rover's own controller runs them: a trapezoidal speed profile in the odometry's
distance or heading. ``RoverSim.run`` runs one task per rover at the same time,
with an optional arm motion each (``ArmWave``).

Command line (``rover_drive_command``)::

    rover-drive build/mira3d-floor --distance 10 --speed 0.5 --report r.json
    rover-drive build/mira3d-pair --rover collector --distance 5 --turn 90 --arm
    rover-drive build/mira3d-pair --plan plan.yaml

The package, one module per job: ``roles`` (the rovers of a facility as MuJoCo ids),
``odometry`` (dead reckoning and the true pose), ``tasks`` (the closed loops and the
arm motion, and ``TASKS``: their registered kinds), ``plan_file`` (a task plan file),
``sim`` (stepping, wheel commands, the brake), ``report`` (what a task did), ``state``
(what tasks and reports read of ``sim``) and ``cli`` (``rover-drive``).
"""

from .cli import rover_drive_command
from .odometry import Odometry, Pose, true_pose
from .plan_file import Plan, check_plan, read_plan
from .report import TaskReport
from .roles import Rover, RoverError, find_rovers
from .sim import RoverSim
from .tasks import TASKS, ArmWave, Hold, Straight, Task, TaskKind, Turn

__all__ = [
    "TASKS",
    "ArmWave",
    "Hold",
    "Odometry",
    "Plan",
    "Pose",
    "Rover",
    "RoverError",
    "RoverSim",
    "Straight",
    "Task",
    "TaskKind",
    "TaskReport",
    "Turn",
    "check_plan",
    "find_rovers",
    "read_plan",
    "rover_drive_command",
    "true_pose",
]
