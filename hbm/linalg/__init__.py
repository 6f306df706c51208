"""Linear algebra of the solvers: the solver protocol, direct solves, GMRES, the bordered
system. Leaf modules: numpy and scipy only."""
