"""`poles demo`: the whole pipeline, stage by stage, on the embedded synthetic default."""
