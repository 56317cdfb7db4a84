"""Range and bearing calibration: measuring poles of known distance and fitting the power laws."""
