"""urdf2mjcf: compile URDF and xacro robot descriptions into MuJoCo MJCF."""

__version__ = "0.1.0"

from .api import ConvertOptions, build, convert, make_options  # noqa: E402
from .errors import ConversionError  # noqa: E402
from .report import Report  # noqa: E402

__all__ = ["ConvertOptions", "ConversionError", "Report", "build", "convert", "make_options"]
