"""The simulated skin: digital twin, sensors, fingers and named scenarios."""
