"""Controllers: pump logic (and, later, the MPC and the Peltier inner loop)."""
