"""The robot front end's crop network on the training side: crops of rendered (or a team's) frames with their
targets, the network, its training and its export. The runtime half lives in ``naoslam`` (candidates, crops,
``CropDetector``)."""
