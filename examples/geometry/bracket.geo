// An L-shaped bracket (metres): two plates 20 mm x 10 mm x 6 mm joined at
// a corner - a foot on z = 0 along x and an upright along z - meshed in
// tetrahedra. Its volume is exactly (20 x 6 + 6 x 14) x 10 mm^3 = 2.04e-6 m^3.
// Physical groups: "bracket" (the volume), "foot" (its face on z = 0).
// Made into bracket.msh (Gmsh format 4.1, ASCII) by:
//   gmsh -3 -format msh41 bracket.geo -o bracket.msh
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 0.020, 0.010, 0.006};
Box(2) = {0, 0, 0, 0.006, 0.010, 0.020};
BooleanUnion(3) = {Volume{1}; Delete;}{Volume{2}; Delete;};
Mesh.MeshSizeMax = 0.003;
Physical Volume("bracket") = {3};
foot() = Surface In BoundingBox{-1e-4, -1e-4, -1e-4, 0.0201, 0.0101, 1e-4};
Physical Surface("foot") = {foot()};
