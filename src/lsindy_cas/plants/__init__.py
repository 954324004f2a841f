"""Plants simulated by independent engines (MuJoCo), in the project's coordinates: judges for the
identification and the controller.  Optional: ``mujoco`` is imported when a plant is built."""
