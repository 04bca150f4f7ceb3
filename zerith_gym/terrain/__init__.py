"""The ground: the plane, height fields and tile grids (`ground`), the tiles' kinds (`tiles`), and the
terrain curriculum's levels (`levels`)."""
