"""The paper's experiments (Sec. VI) on the simulated skin: scenarios, runs, figures, report."""
