"""urdf2mjcf: compile URDF and xacro robot descriptions into MuJoCo MJCF."""

__version__ = "0.1.0"
