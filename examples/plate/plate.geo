// A 2 × 1 plate with a hole of radius 0.2 at (1.4, 0.5).
SetFactory("OpenCASCADE");
Rectangle(1) = {0, 0, 0, 2, 1};
Disk(2) = {1.4, 0.5, 0, 0.2};
BooleanDifference(3) = { Surface{1}; Delete; }{ Surface{2}; Delete; };
Mesh.MeshSizeMax = 0.05;
