"""Run tasks in a built facility: replay the iMETRO logistics demo and judge it, drive rovers.

The runner knows only a compiled facility (``scene.xml``) and its manifest
(``facility.json``): it looks up the robot's joints, actuators, sensors,
cameras and sites by the names the manifest gives for the robot's roles, and
drives the robot only through its actuators. One module per concern:

``load``        scene + manifest -> :class:`~urdf2mjcf.runner.load.Facility`
``control``     stepping, smooth joint trajectories, the gripper, settle checks
``ik``          mink differential IK of the grasp site over the robot's joints, on a copy
``hinge``       an arc of tool poses around a hinge joint of the loaded model
``perception``  wrist camera RGB-D, red mask, PCA, back-projection -> grasp pose
``judge``       intended vs unintended contacts, and the success test
``demo``        the waypoints file and the steps of the demo
``trials``      seeded trials in parallel processes
``cli``         ``facility-demo``
``rover``       MIRA3D rovers (a package: roles, odometry, tasks, sim, report, ``rover-drive``)
"""
