"""Motion as data: rigid poses of the ego vehicle and the scene's objects at any time
(:mod:`simlidar.motion.poses`), from which each pulse is cast at its own emission time
(:func:`simlidar.sensor.moving.cast_moving`)."""
