"""Cameras: the calibration board (ChArUco, OpenCV's aruco module), image sources (the
twin's rendered camera, or a real camera driver), hand-eye calibration, and turning a
detection in a camera's frame into a pose in the world. OpenCV is the optional extra
``vision`` (``pip install 'cellrunner[vision]'``) and is imported only here, lazily."""
