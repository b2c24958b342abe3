"""Run tasks in a built facility: replay the iMETRO logistics demo and judge it, drive rovers.

The runner reads a built bundle (``facility.json`` and the ``scene.xml`` it names, the
demo and waypoints files beside them) and the files a user passes (a waypoints file, a
rover plan); it looks up the robot's joints, actuators, sensors, cameras and sites by
the names the manifest gives for the robot's roles, and drives the robot only through
its actuators. One module per concern (tests/test_architecture_claims.py checks the
list is whole):

``load``             scene + manifest -> :class:`~urdf2mjcf.runner.load.Facility`
``sim``              the one place the runtime steps MuJoCo, with its callbacks in order
``control``          stepping, smooth joint trajectories, the gripper, settle checks
``ik``               mink differential IK of the grasp site over the robot's joints, on a copy
``hinge``            an arc of tool poses around a hinge joint of the loaded model
``plan``             collision-free joint moves (OMPL RRT*), timed by TOPP-RA
``camera``           the one camera model: world to pixels
``noise``            seeded sensor noise on depth, images and the wrench
``perception``       wrist camera RGB-D, red mask, PCA, back-projection -> grasp pose
``localize``         the components found by their AprilTags
``judge``            intended vs unintended contacts, and the success test
``checks``           checks of a stranger's waypoints file: numbers, names, lists, mappings
``waypoints``        the demo's waypoints file, checked before anything moves
``steps``            the demo's step kinds, one registered class each
``task_kinds``       every task kind's parameters declared once (type, unit, range, default)
``demo``             the steps of the demo, executed and judged one by one
``trials``           seeded trials, each on a facility rebuilt with its seed
``trial_options``    ``--workers`` and ``--executor``, declared once
``executors``        a local process pool or a Ray cluster
``aggregate``        what trials add up to: a success rate with its Wilson interval
``record``           ROS 2 recordings (MCAP) of a run
``cdr``              ROS 2 CDR encoding of a message
``foxglove_server``  Foxglove's WebSocket protocol, served on the loopback interface
``foxglove_live``    a run streamed live to Foxglove
``live_options``     the options that watch a run live, declared once
``cli``              ``facility-demo``
``rover``            MIRA3D rovers (a package: roles, odometry, tasks, sim, report, ``rover-drive``)
"""
