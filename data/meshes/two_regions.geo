// The rectangle (0, 2) x (0, 1) in two physical surfaces, "loaded" (x < 1) and "free" (x > 1),
// whose common side x = 1 is a curve of both (so the mesh has edges on it); the physical curves
// "rim" (the side x = 2) and "clamped" (the other sides). For data/cases/two_regions.toml:
//     gmsh two_regions.geo -2 -format msh41 -o two_regions.msh
// (two_regions.msh as shipped was written by two_regions.py, a structured mesh of the same groups,
// on a machine without Gmsh.)
h = 0.125;
Point(1) = {0, 0, 0, h};
Point(2) = {1, 0, 0, h};
Point(3) = {2, 0, 0, h};
Point(4) = {2, 1, 0, h};
Point(5) = {1, 1, 0, h};
Point(6) = {0, 1, 0, h};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 5};
Line(5) = {5, 6};
Line(6) = {6, 1};
Line(7) = {2, 5};
Curve Loop(1) = {1, 7, 5, 6};
Plane Surface(1) = {1};
Curve Loop(2) = {2, 3, 4, -7};
Plane Surface(2) = {2};
Physical Curve("clamped", 1) = {1, 2, 4, 5, 6};
Physical Curve("rim", 2) = {3};
Physical Surface("loaded", 3) = {1};
Physical Surface("free", 4) = {2};
