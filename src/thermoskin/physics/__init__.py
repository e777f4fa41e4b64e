"""Physics of the skin: water, convection, the thermal network, the finger."""
