// The unit cube [0, 1]^3 in tetrahedra (physical volume "cube"), faces
// z = 0 in physical surface "bottom"; for tests/test_geometry_files.cpp:
//   gmsh -3 -format msh41 cube_tets.geo -o cube_tets.msh
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 1, 1};
Mesh.MeshSizeMax = 0.5;
Physical Volume("cube") = {1};
Physical Surface("bottom") = {5};
