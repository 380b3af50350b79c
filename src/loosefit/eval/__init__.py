"""Evaluation metrics for predicted garment sequences against ground truth."""
