"""Synthetic pole scenes: a calibrated Nao camera, 3D cylinders on a field, exact masks, ranges and bearings."""
