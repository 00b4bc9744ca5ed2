// The embankment of examples/geometry/embankment.toml (plane strain, metres):
// 12 m wide at its base (y = 0), 3 m high, a 3 m crest, with a 2 m wide
// core. Physical groups: "core" (quadrangles), "fill" (the two shoulders,
// triangles) and "base" (the three lines on y = 0). Made into
// embankment.msh (Gmsh format 4.1, binary) by:
//   gmsh -2 -format msh41 -bin embankment.geo -o embankment.msh
h = 0.4;
Point(1) = {0, 0, 0, h};   Point(2) = {5, 0, 0, h};   Point(3) = {7, 0, 0, h};   Point(4) = {12, 0, 0, h};
Point(5) = {7.5, 3, 0, h}; Point(6) = {7, 3, 0, h};   Point(7) = {5, 3, 0, h};   Point(8) = {4.5, 3, 0, h};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 5};
Line(5) = {5, 6}; Line(6) = {6, 7}; Line(7) = {7, 8}; Line(8) = {8, 1};
Line(9) = {2, 7}; Line(10) = {3, 6};
Curve Loop(1) = {1, 9, 7, 8};    Plane Surface(1) = {1}; // left shoulder
Curve Loop(2) = {2, 10, 6, -9};  Plane Surface(2) = {2}; // core
Curve Loop(3) = {3, 4, 5, -10};  Plane Surface(3) = {3}; // right shoulder
Transfinite Curve{2, 6} = 6;
Transfinite Curve{9, 10} = 9;
Transfinite Surface{2};
Recombine Surface{2};
Physical Surface("fill") = {1, 3};
Physical Surface("core") = {2};
Physical Curve("base") = {1, 2, 3};
