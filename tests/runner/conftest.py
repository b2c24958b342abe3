from urdf2mjcf import headless

headless.configure()  # before mujoco is imported by the tests
