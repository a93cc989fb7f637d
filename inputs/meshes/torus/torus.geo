// A soft torus for the torus-drop benchmark (issue 18): major radius R = 50 mm, tube
// radius r = 15 mm, tetrahedra of 8 to 12 mm. Units: metres.
SetFactory("OpenCASCADE");
Torus(1) = {0, 0, 0, 0.05, 0.015};
Mesh.CharacteristicLengthMin = 0.008;
Mesh.CharacteristicLengthMax = 0.012;
Mesh.Algorithm3D = 1;
Mesh.RandomSeed = 1;
