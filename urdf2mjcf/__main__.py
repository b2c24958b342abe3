from .cli import urdf2mjcf_main

urdf2mjcf_main()
