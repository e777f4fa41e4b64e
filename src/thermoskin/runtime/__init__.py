"""Runtime: the per-sample loop that feeds the blocks and listens to them."""
