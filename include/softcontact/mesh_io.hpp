#pragma once
// Reading tetrahedral meshes from Gmsh (.msh) and TetGen (.node/.ele) files, and writing
// Gmsh files. docs/mesh-formats.md lists what is accepted and rejected, with example
// error messages.
//
// Gmsh MSH 2.2 (ASCII, file-type 0):
//   $MeshFormat / 2.2 0 8 / $EndMeshFormat
//   $Nodes / <count> / <node-tag> <x> <y> <z>   (one node per line) / $EndNodes
//   $Elements / <count> /
//     <elm-tag> <elm-type> <num-tags> <tag>... <node-tag>...   (one element per line)
//   $EndElements
// Gmsh MSH 2.2 binary (file-type 1): the version line is followed by the int32 1 in the
//   writer's byte order (either order is read); the counts of $Nodes and $Elements are
//   ASCII lines; nodes are int32 tag + 3 float64; elements come in blocks of
//   int32 (elm-type, count, num-tags) then per element int32 (tag, tags..., nodes...).
// Gmsh MSH 4.1 (ASCII):
//   $Nodes / numEntityBlocks numNodes minNodeTag maxNodeTag /
//     per block: entityDim entityTag parametric numNodesInBlock / numNodesInBlock lines
//     with one node tag each / numNodesInBlock lines "x y z" (followed by entityDim
//     parametric coordinates u [v [w]] when parametric is 1; they are read and ignored)
//   $Elements / numEntityBlocks numElements minElementTag maxElementTag /
//     per block: entityDim entityTag elementType numElementsInBlock / one line per
//     element: elementTag nodeTag...
// Gmsh MSH 4.1 binary: the same fields, with size_t (8 bytes) for counts and tags, int32
//   for entityDim, entityTag, parametric and elementType, float64 for coordinates.
// In every Gmsh file, sections other than $MeshFormat, $Nodes and $Elements
// ($PhysicalNames, $Entities, $PartitionedEntities, $NodeData, ...) are skipped up to
// their $End line. Only linear tetrahedra (type 4) become tets; points, lines and surface
// elements (types 1-3, 8-10, 15, 16, 20-28) are skipped; any other volume element (e.g.
// 10-node tets, type 11) or an unknown type is rejected.
//
// TetGen:
//   X.node: <#points> <dimension = 3> [<#attributes> [<boundary markers 0|1>]]
//           then per point: <index> <x> <y> <z> [attributes...] [marker]
//   X.ele:  <#tets> <nodes per tet = 4> [<#attributes>]
//           then per tet: <index> <n1> <n2> <n3> <n4> [attributes...]
//   '#' starts a comment; the first point index (0 or 1) fixes the numbering of both files.
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "softcontact/mesh.hpp"

namespace softcontact {

/// Reads a tetrahedral mesh, choosing the reader by extension: .msh -> Gmsh (2.2 or 4.1,
/// ASCII or binary, detected from $MeshFormat); .node or .ele -> TetGen (reads both
/// X.node and X.ele for the same stem X). The result is validated with validate_mesh
/// (inverted tets reoriented, unreferenced vertices removed, with warnings in *report).
/// Throws InputError naming the file, the line (ASCII) or element, and what was expected.
TetMesh read_mesh(const std::string& path, MeshReport* report = nullptr);

/// How many mesh files this process has read (read_mesh calls, the failed ones included):
/// the set-up's file reading per rank, for tests and diagnostics.
std::uint64_t mesh_files_read();
TetMesh read_gmsh(const std::string& path, MeshReport* report = nullptr);
TetMesh read_tetgen(const std::string& path, MeshReport* report = nullptr);

/// The same readers on a file's bytes already in memory (tests, fuzzing, other sources);
/// the names stand for the files in messages, nothing is opened.
TetMesh read_gmsh_bytes(std::string_view bytes, const std::string& name, MeshReport* report = nullptr);
TetMesh read_tetgen_bytes(std::string_view node_bytes, std::string_view ele_bytes, const std::string& node_name,
                          const std::string& ele_name, MeshReport* report = nullptr);

/// A mesh, and what reading it reported, as bytes to send between ranks: vertex and tet
/// counts (64-bit), the points and tets as stored, then the report's two counts and its
/// warnings (each a 64-bit length and the text). take_mesh_bytes reads one back from
/// `at` (bitwise the mesh appended) and moves `at` past it; RuntimeFailure when the bytes
/// end early.
void append_mesh_bytes(std::vector<char>& bytes, const TetMesh& mesh, const MeshReport* report = nullptr);
TetMesh take_mesh_bytes(const std::vector<char>& bytes, std::size_t& at, MeshReport* report = nullptr);

enum class GmshFormat { v22_ascii, v22_binary, v41_ascii, v41_binary };

/// Writes the tets (element type 4) and their nodes; node tags 1..n, element tags 1..m.
/// Coordinates are written so that reading them back gives the same doubles bit for bit
/// (shortest round-trip decimal in ASCII, native float64 in binary).
/// Throws RuntimeFailure when the file cannot be written.
void write_gmsh(const std::string& path, const TetMesh& mesh, GmshFormat format);

}  // namespace softcontact
