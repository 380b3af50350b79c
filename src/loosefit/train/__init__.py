"""Training loops of the learned stages."""
