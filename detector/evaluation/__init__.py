"""Precision, recall and mask IoU per image on held-out frames, counted as the 2024 thesis did."""
