"""The training side of ``poles slam``: sequences for the runtime's filters (a simulated walk, its frames rendered
and seen through a front end, a UTIAS log, a recording), the back-end comparison, the GTSAM smoother reference,
and the files and plots a run writes. The filters themselves are naoslam's; nothing here runs on the robot."""
