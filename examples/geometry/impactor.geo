// The impactor of examples/geometry/impactor.toml: a steel cylinder, radius
// 5 mm and length 20 mm along z, with a hemispherical nose (radius 5 mm) at
// z = 0 and a groove round its waist (a non-convex surface), in metres.
// Made into impactor.stl (binary STL) by:
//   gmsh -2 -format stl -bin impactor.geo -o impactor.stl
SetFactory("OpenCASCADE");
R = 0.005; L = 0.02;
Cylinder(1) = {0, 0, 0, 0, 0, L, R};
Sphere(2) = {0, 0, 0, R};
Torus(3) = {0, 0, 0.6 * L, R, 0.3 * R};
BooleanUnion(4) = { Volume{1}; Delete; }{ Volume{2}; Delete; };
BooleanDifference(5) = { Volume{4}; Delete; }{ Volume{3}; Delete; };
Mesh.MeshSizeMin = 0.0012;
Mesh.MeshSizeMax = 0.0012;
