// The unit square, meshed by Gmsh's default Frontal-Delaunay algorithm to size 0.125: an
// unstructured mesh for data/cases/gmsh_square.toml. Regenerate with
//   gmsh square.geo -2 -format msh41 -o square.msh
// Physical groups are written (as Gmsh users do) but ignored by membrane-contact: every triangle
// is part of ω and ∂ω is the boundary of the triangulation.
lc = 0.125;
Point(1) = {0, 0, 0, lc};
Point(2) = {1, 0, 0, lc};
Point(3) = {1, 1, 0, lc};
Point(4) = {0, 1, 0, lc};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Physical Curve("boundary", 1) = {1, 2, 3, 4};
Physical Surface("omega", 2) = {1};
