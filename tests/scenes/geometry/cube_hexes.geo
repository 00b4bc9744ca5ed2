// The box [0, 2] x [0, 1] x [0, 1] in 4 x 2 x 2 hexahedra (physical volume
// "box"), for tests/test_geometry_files.cpp:
//   gmsh -3 -format msh41 cube_hexes.geo -o cube_hexes.msh
Point(1) = {0, 0, 0}; Point(2) = {2, 0, 0}; Point(3) = {2, 1, 0}; Point(4) = {0, 1, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Transfinite Curve{1, 3} = 5; Transfinite Curve{2, 4} = 3;
Transfinite Surface{1}; Recombine Surface{1};
Extrude {0, 0, 1} { Surface{1}; Layers{2}; Recombine; }
Physical Volume("box") = {1};
