#pragma once
// The OBJ parser behind rt/io/load_obj.h: an OBJ file's text to its vertices, faces, materials and
// shapes, read as tinyobjloader 2.0.0rc10 read them, in parallel chunks. Internal to the io module.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <tiny_obj_loader.h>

#include "rt/io/load_obj.h"

namespace rt {

// One corner of a face: 0-based indices as tinyobj's parseTriple and fixIndex give them; -1 for an
// absent texcoord or normal (a relative index that comes to -1 reads the same, as in tinyobj).
struct ObjCorner {
  std::int32_t position = -1, texcoord = -1, normal = -1;
};

// The faces one chunk kept, their indices resolved and checked: face f of the block has the
// corners [ends[f - 1], ends[f]) (from 0 for f = 0). Kept where parsing put them: copying them
// into one array would cost a pass over them and fresh memory.
struct ObjFaceBlock {
  std::vector<ObjCorner> corners;
  std::vector<std::size_t> ends;
};

// A parsed OBJ file: every face kept, in file order, numbered from 0 across the blocks.
struct ObjFile {
  std::vector<float> positions;           // x y z per v: float32 as written (object or world space)
  std::vector<float> normals;             // x y z per vn, as written
  std::vector<float> texcoords;           // u v per vt, v = 0 at the image's bottom (OBJ)
  std::vector<std::uint8_t> normal_usable;  // per vn: finite, non-zero length (in double)
  std::vector<ObjFaceBlock> blocks;
  std::vector<std::size_t> block_starts;  // block b: faces [block_starts[b], block_starts[b + 1])
  std::vector<std::pair<std::size_t, int>> material_runs;  // (first face, index into materials or -1)
  std::vector<std::size_t> shape_starts;  // shape s: faces [shape_starts[s], shape_starts[s + 1])
  std::vector<tinyobj::material_t> materials;
  std::vector<std::string> missing_libraries;
  std::vector<std::string> unknown_materials;  // usemtl names no library defines
  std::size_t position_count() const { return positions.size() / 3; }
  std::size_t normal_count() const { return normals.size() / 3; }
  std::size_t texcoord_count() const { return texcoords.size() / 2; }
  std::size_t face_count() const { return block_starts.back(); }
};

// Calls visit(corners, n) for the faces [first, end) in order, each with its n corners.
template <class Visit>
void for_each_face(const ObjFile& obj, std::size_t first, std::size_t end, Visit&& visit) {
  std::size_t b = std::size_t(std::upper_bound(obj.block_starts.begin(), obj.block_starts.end(), first) -
                              obj.block_starts.begin()) - 1;
  for (std::size_t f = first; f < end; ++b) {
    const ObjFaceBlock& block = obj.blocks[b];
    for (; f < end && f < obj.block_starts[b + 1]; ++f) {
      const std::size_t local = f - obj.block_starts[b], begin = local == 0 ? 0 : block.ends[local - 1];
      visit(block.corners.data() + begin, block.ends[local] - begin);
    }
  }
}

// Reads the OBJ at `path` and the MTL libraries it names, and checks it: numbers of v, vn and vt
// lines (finite, as strtod reads them), no binary data, statements tinyobjloader could parse,
// world coordinates within kMaxWorldCoordinate, at least one face, every index in range. Throws
// InputError "FILE:LINE: REASON" for the first problem, in the order the old loader found them.
ObjFile read_obj(const std::string& path, const ObjLoadOptions& options);

}  // namespace rt
