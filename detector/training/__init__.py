"""Training with Ultralytics: where a run starts (the shipped checkpoint, torch-free), the run itself and its curves,
the CPU thread count and wait policy for a shared machine, and blending two checkpoints."""
