"""Offline augmentation as the 2024 thesis did it: 7 copies per training image, labels kept exact."""
