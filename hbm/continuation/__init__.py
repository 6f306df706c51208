"""Arc-length continuation and the one Newton loop, for any residual callable and LinearSolver."""
