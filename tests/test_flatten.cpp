// flatten_scene: world-space positions and normals against transforms written out by hand.

#include "catch.h"

#include <cmath>
#include <functional>
#include <limits>

#include "rt/core/error.h"
#include "rt/flatten/flatten.h"
#include "rt/scene/shapes.h"
#include "test_util.h"

namespace {

using rt::Mat4d;
using rt::Vec3d;
using rt::Vec3f;
using Map = std::function<Vec3d(const Vec3d&)>;

// GLM is column-major: m[column][row].
Mat4d translation(Vec3d t) {
  Mat4d m(1.0);
  m[3] = rt::Vec4d(t, 1.0);
  return m;
}
Mat4d scaling(Vec3d s) {
  Mat4d m(1.0);
  m[0][0] = s.x;
  m[1][1] = s.y;
  m[2][2] = s.z;
  return m;
}
// 90 degrees about +z: x -> y, y -> -x.
Mat4d rotation_z90() {
  Mat4d m(0.0);
  m[0][1] = 1.0;   // column x -> (0, 1, 0)
  m[1][0] = -1.0;  // column y -> (-1, 0, 0)
  m[2][2] = 1.0;
  m[3][3] = 1.0;
  return m;
}

// An asymmetric, oblique triangle, so that swapped or mis-signed components show.
rt::TriangleMesh oblique_triangle() {
  return rt_test::make_flat_mesh({{Vec3f(0.5f, -0.25f, 0.2f), Vec3f(1.5f, 0.5f, -0.3f), Vec3f(-0.4f, 1.0f, 0.7f)}});
}

bool close(const Vec3d& a, const Vec3d& b, double tolerance) {
  return std::abs(a.x - b.x) <= tolerance && std::abs(a.y - b.y) <= tolerance && std::abs(a.z - b.z) <= tolerance;
}

std::string str(const Vec3d& v) {
  return "(" + std::to_string(v.x) + ", " + std::to_string(v.y) + ", " + std::to_string(v.z) + ")";
}

// Checks every property the flattener promises for one model whose vertices start at `base`
// and whose triangles start at `first_triangle`: positions = position_map(p), normals =
// normalize(normal_map(n)), unit length, perpendicular to the world-space (flat) triangle edges,
// and the geometric normal (p1 - p0) x (p2 - p0) on the same side as the vertex normals.
void check_model(const rt::FlatScene& flat, const rt::TriangleMesh& mesh, std::size_t base, std::size_t first_triangle,
                 const Map& position_map, const Map& normal_map) {
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    const Vec3d expected_p = position_map(Vec3d(mesh.positions[i]));
    const Vec3d actual_p(flat.positions[base + i]);
    INFO("vertex " << i << ": position " << str(actual_p) << ", expected " << str(expected_p));
    CHECK(close(actual_p, expected_p, 1e-6 * (1.0 + glm::length(expected_p))));
    const Vec3d expected_n = glm::normalize(normal_map(Vec3d(mesh.normals[i])));
    const Vec3d actual_n(flat.normals[base + i]);
    INFO("normal " << str(actual_n) << ", expected " << str(expected_n));
    CHECK(close(actual_n, expected_n, 1e-6));
    CHECK(glm::length(actual_n) == Approx(1.0).margin(1e-6));
  }
  for (std::size_t k = 0; k < mesh.triangles.size(); ++k) {
    const rt::Vec3u tri = flat.triangles[first_triangle + k];
    const rt::Vec3u original = mesh.triangles[k] + rt::Vec3u(static_cast<unsigned>(base));
    // Same three vertices (the order may change under a mirror).
    for (int c = 0; c < 3; ++c) CHECK((tri[c] == original.x || tri[c] == original.y || tri[c] == original.z));
    CHECK(tri.x + tri.y + tri.z == original.x + original.y + original.z);
    const Vec3d p0(flat.positions[tri.x]), p1(flat.positions[tri.y]), p2(flat.positions[tri.z]);
    const Vec3d geometric = glm::normalize(glm::cross(p1 - p0, p2 - p0));
    for (int c = 0; c < 3; ++c) {
      const Vec3d n(flat.normals[tri[c]]);
      INFO("triangle " << k << " corner " << c << ": geometric normal " << str(geometric) << ", vertex normal "
                       << str(n));
      // The test meshes are flat, so the vertex normal must be the geometric normal, same sign.
      CHECK(glm::dot(geometric, n) > 0.0);
      CHECK(std::abs(glm::dot(n, glm::normalize(p1 - p0))) < 1e-5);
      CHECK(std::abs(glm::dot(n, glm::normalize(p2 - p0))) < 1e-5);
      CHECK(std::abs(glm::dot(n, glm::normalize(p2 - p1))) < 1e-5);
      CHECK(glm::dot(geometric, n) == Approx(1.0).margin(1e-5));
    }
  }
}

// A root node (identity) with one child carrying `transform` and the given models.
rt::Scene one_child_scene(const Mat4d& transform, const rt::TriangleMesh& mesh) {
  rt::Scene scene = rt_test::make_scene({});
  scene.materials.resize(1);
  rt::Node child;
  child.name = "child";
  child.parent_from_node = transform;
  child.models.push_back({std::make_shared<const rt::TriangleMesh>(mesh), 0});
  scene.nodes.push_back(child);
  scene.nodes[0].children.push_back(1);
  return scene;
}

}  // namespace

TEST_CASE("flatten with identity transforms copies the mesh", "[flatten]") {
  const rt::TriangleMesh mesh = rt::make_cube_mesh();
  rt::Scene scene = rt_test::make_scene({{mesh, 0}});
  scene.materials.resize(1);
  const rt::FlatScene flat = rt::flatten_scene(scene);
  REQUIRE(flat.positions.size() == mesh.positions.size());
  REQUIRE(flat.normals.size() == mesh.normals.size());
  REQUIRE(flat.triangles.size() == 12);
  REQUIRE(flat.triangle_count() == 12);
  REQUIRE(flat.material_ids.size() == 12);
  CHECK(flat.positions == mesh.positions);
  CHECK(flat.normals == mesh.normals);
  CHECK(flat.triangles == mesh.triangles);
  CHECK(flat.positions.capacity() > flat.positions.size());
}

TEST_CASE("flatten applies a node's transform to positions and normals", "[flatten]") {
  for (const rt::TriangleMesh& mesh : {oblique_triangle(), rt::make_cube_mesh()}) {
    DYNAMIC_SECTION("mesh with " << mesh.triangles.size() << " triangles") {
      Mat4d transform(1.0);
      Map position_map, normal_map;
      SECTION("translate") {
        transform = translation({1.0, -2.0, 3.5});
        position_map = [](const Vec3d& p) { return p + Vec3d(1.0, -2.0, 3.5); };
        normal_map = [](const Vec3d& n) { return n; };
      }
      SECTION("rotate 90 degrees about z") {
        transform = rotation_z90();
        position_map = [](const Vec3d& p) { return Vec3d(-p.y, p.x, p.z); };
        normal_map = [](const Vec3d& n) { return Vec3d(-n.y, n.x, n.z); };
      }
      SECTION("non-uniform scale") {
        // Normals transform by the inverse transpose, diag(1/2, 1/3, 1/4).
        transform = scaling({2.0, 3.0, 4.0});
        position_map = [](const Vec3d& p) { return Vec3d(2.0 * p.x, 3.0 * p.y, 4.0 * p.z); };
        normal_map = [](const Vec3d& n) { return Vec3d(n.x / 2.0, n.y / 3.0, n.z / 4.0); };
      }
      SECTION("mirror in x") {
        transform = scaling({-1.0, 1.0, 1.0});
        position_map = [](const Vec3d& p) { return Vec3d(-p.x, p.y, p.z); };
        normal_map = [](const Vec3d& n) { return Vec3d(-n.x, n.y, n.z); };
      }
      SECTION("mirror with non-uniform scale, rotation and translation") {
        // T R S with S = diag(-2, 1, 0.5): p -> R(S p) + t, n -> R(S^-1 n).
        transform = translation({0.0, 1.0, -1.0}) * rotation_z90() * scaling({-2.0, 1.0, 0.5});
        position_map = [](const Vec3d& p) { return Vec3d(-p.y, -2.0 * p.x, 0.5 * p.z) + Vec3d(0.0, 1.0, -1.0); };
        normal_map = [](const Vec3d& n) { return Vec3d(-n.y, -n.x / 2.0, 2.0 * n.z); };
      }
      SECTION("mirror in all three axes") {
        transform = scaling({-1.0, -1.0, -1.0});
        position_map = [](const Vec3d& p) { return -p; };
        normal_map = [](const Vec3d& n) { return -n; };
      }
      if (position_map) {
        const rt::FlatScene flat = rt::flatten_scene(one_child_scene(transform, mesh));
        REQUIRE(flat.positions.size() == mesh.positions.size());
        REQUIRE(flat.normals.size() == mesh.positions.size());
        REQUIRE(flat.triangles.size() == mesh.triangles.size());
        check_model(flat, mesh, 0, 0, position_map, normal_map);
        CHECK(flat.positions.capacity() > flat.positions.size());
      }
    }
  }
}

TEST_CASE("flatten composes nested transforms as parent * child", "[flatten]") {
  // root -> a (rotate 90 about z) -> b (translate (1, 0, 0)) -> c (scale (1, 2, 1)).
  // world_from_c = R T S: p -> R(S p + (1, 0, 0)) = (-2y, x + 1, z); normals -> R S^-1 n.
  // Composing child * parent instead (S T R) would give (-y, 2x + 2, z).
  const rt::TriangleMesh mesh = oblique_triangle();
  rt::Scene scene = rt_test::make_scene({});
  scene.materials.resize(2);
  rt::Node a, b, c;
  a.name = "a";
  a.parent_from_node = rotation_z90();
  a.children = {2};
  a.models.push_back({std::make_shared<const rt::TriangleMesh>(mesh), 1});
  b.name = "b";
  b.parent_from_node = translation({1.0, 0.0, 0.0});
  b.children = {3};
  c.name = "c";
  c.parent_from_node = scaling({1.0, 2.0, 1.0});
  c.models.push_back({std::make_shared<const rt::TriangleMesh>(mesh), 0});
  scene.nodes.push_back(a);
  scene.nodes.push_back(b);
  scene.nodes.push_back(c);
  scene.nodes[0].children = {1};

  const rt::FlatScene flat = rt::flatten_scene(scene);
  REQUIRE(flat.triangles.size() == 2);
  REQUIRE(flat.positions.size() == 6);
  // Tell the two copies apart by material: a's model (material 1) only gets R.
  for (std::size_t k = 0; k < 2; ++k) {
    const std::size_t base = flat.triangles[k].x / 3 * 3;  // each model contributes 3 vertices
    INFO("triangle " << k << " material " << flat.material_ids[k]);
    if (flat.material_ids[k] == 1) {
      check_model(flat, mesh, base, k, [](const Vec3d& p) { return Vec3d(-p.y, p.x, p.z); },
                  [](const Vec3d& n) { return Vec3d(-n.y, n.x, n.z); });
    } else {
      REQUIRE(flat.material_ids[k] == 0);
      check_model(flat, mesh, base, k, [](const Vec3d& p) { return Vec3d(-2.0 * p.y, p.x + 1.0, p.z); },
                  [](const Vec3d& n) { return Vec3d(-n.y / 2.0, n.x, n.z); });
    }
  }
  CHECK(flat.material_ids[0] != flat.material_ids[1]);
}

TEST_CASE("flatten keeps cube faces outward and consistent under a mirror", "[flatten]") {
  const rt::FlatScene flat =
      rt::flatten_scene(one_child_scene(translation({3.0, 0.0, 0.0}) * scaling({-1.0, 2.0, 0.5}), rt::make_cube_mesh()));
  REQUIRE(flat.triangles.size() == 12);
  const Vec3d centre(3.0, 0.0, 0.0);
  for (const rt::Vec3u& tri : flat.triangles) {
    const Vec3d p0(flat.positions[tri.x]), p1(flat.positions[tri.y]), p2(flat.positions[tri.z]);
    const Vec3d geometric = glm::cross(p1 - p0, p2 - p0);
    const Vec3d outward = (p0 + p1 + p2) / 3.0 - centre;
    CHECK(glm::dot(geometric, outward) > 0.0);
    for (int c = 0; c < 3; ++c) CHECK(glm::dot(Vec3d(flat.normals[tri[c]]), outward) > 0.0);
  }
}

TEST_CASE("flatten computes unit normals for meshes without them, also when mirrored", "[flatten]") {
  rt::TriangleMesh mesh = oblique_triangle();
  const Vec3d face_normal(mesh.normals[0]);
  mesh.normals.clear();
  const rt::FlatScene flat = rt::flatten_scene(one_child_scene(scaling({1.0, -1.0, 1.0}), mesh));
  REQUIRE(flat.normals.size() == 3);
  const rt::Vec3u tri = flat.triangles[0];
  const Vec3d p0(flat.positions[tri.x]), p1(flat.positions[tri.y]), p2(flat.positions[tri.z]);
  const Vec3d geometric = glm::normalize(glm::cross(p1 - p0, p2 - p0));
  for (const Vec3f& n : flat.normals) {
    CHECK(glm::length(Vec3d(n)) == Approx(1.0).margin(1e-6));
    CHECK(glm::dot(Vec3d(n), geometric) == Approx(1.0).margin(1e-6));
    CHECK(close(Vec3d(n), Vec3d(face_normal.x, -face_normal.y, face_normal.z), 1e-6));
  }
}

TEST_CASE("flatten records one material id per triangle", "[flatten]") {
  // Two models on the root, material 2 for the cube and 0 for the triangle, and a child node
  // with material 1, lifted to z = 10 so its triangles can be recognised by position.
  rt::Scene scene = rt_test::make_scene({{rt::make_cube_mesh(), 2}, {oblique_triangle(), 0}});
  scene.materials.resize(3);
  rt::Node child;
  child.parent_from_node = translation({0.0, 0.0, 10.0});
  child.models.push_back({std::make_shared<const rt::TriangleMesh>(rt::make_cube_mesh()), 1});
  scene.nodes.push_back(child);
  scene.nodes[0].children.push_back(1);

  const rt::FlatScene flat = rt::flatten_scene(scene);
  REQUIRE(flat.triangles.size() == 12 + 1 + 12);
  REQUIRE(flat.material_ids.size() == flat.triangles.size());
  int counts[3] = {0, 0, 0};
  for (std::size_t k = 0; k < flat.triangles.size(); ++k) {
    const std::uint32_t id = flat.material_ids[k];
    REQUIRE(id < 3);
    ++counts[id];
    const float z = flat.positions[flat.triangles[k].x].z;
    CHECK((id == 1) == (z > 5.0f));
  }
  CHECK(counts[0] == 1);
  CHECK(counts[1] == 12);
  CHECK(counts[2] == 12);
  // Within one model the triangles keep their order: the root's cube comes first, then the triangle.
  for (std::size_t k = 0; k < 12; ++k) CHECK(flat.material_ids[k] == 2);
  CHECK(flat.material_ids[12] == 0);
}

TEST_CASE("flatten instantiates a node reached along two paths twice", "[flatten]") {
  // root -> left (x + 5) -> shared, root -> right (y + 5) -> shared.
  const rt::TriangleMesh mesh = oblique_triangle();
  rt::Scene scene = rt_test::make_scene({});
  scene.materials.resize(1);
  rt::Node left, right, shared;
  left.parent_from_node = translation({5.0, 0.0, 0.0});
  left.children = {3};
  right.parent_from_node = translation({0.0, 5.0, 0.0});
  right.children = {3};
  shared.parent_from_node = scaling({2.0, 2.0, 2.0});
  shared.models.push_back({std::make_shared<const rt::TriangleMesh>(mesh), 0});
  scene.nodes.push_back(left);
  scene.nodes.push_back(right);
  scene.nodes.push_back(shared);
  scene.nodes[0].children = {1, 2};

  const rt::FlatScene flat = rt::flatten_scene(scene);
  REQUIRE(flat.triangles.size() == 2);
  REQUIRE(flat.positions.size() == 6);
  bool seen_left = false, seen_right = false;
  for (std::size_t k = 0; k < 2; ++k) {
    const std::size_t base = flat.triangles[k].x / 3 * 3;
    const Vec3d first(flat.positions[base]);
    if (first.x > 3.0) {
      seen_left = true;
      check_model(flat, mesh, base, k, [](const Vec3d& p) { return 2.0 * p + Vec3d(5.0, 0.0, 0.0); },
                  [](const Vec3d& n) { return n; });
    } else {
      seen_right = true;
      check_model(flat, mesh, base, k, [](const Vec3d& p) { return 2.0 * p + Vec3d(0.0, 5.0, 0.0); },
                  [](const Vec3d& n) { return n; });
    }
  }
  CHECK(seen_left);
  CHECK(seen_right);
  CHECK(flat.positions.capacity() > flat.positions.size());  // the reserve hint counted it once
}

TEST_CASE("flatten rejects cycles", "[flatten]") {
  rt::Scene scene = rt_test::make_scene({{oblique_triangle(), 0}});
  scene.materials.resize(1);
  scene.nodes.resize(3);
  SECTION("a -> b -> a") {
    scene.nodes[0].children = {1};
    scene.nodes[1].children = {2};
    scene.nodes[2].children = {1};
  }
  SECTION("a node that is its own child") {
    scene.nodes[0].children = {1};
    scene.nodes[1].children = {1};
  }
  SECTION("back to the root") {
    scene.nodes[0].children = {1};
    scene.nodes[1].children = {2};
    scene.nodes[2].children = {0};
  }
  CHECK_THROWS_AS(rt::flatten_scene(scene), rt::InputError);
}

TEST_CASE("flatten rejects singular and non-finite transforms", "[flatten]") {
  Mat4d transform(1.0);
  SECTION("zero scale in one axis") { transform = scaling({1.0, 0.0, 1.0}); }
  SECTION("zero scale overall") { transform = scaling({0.0, 0.0, 0.0}); }
  SECTION("rank-deficient shear") {
    transform[1] = transform[0];  // y column equals x column
  }
  SECTION("NaN entry") { transform[0][0] = std::numeric_limits<double>::quiet_NaN(); }
  SECTION("infinite translation") { transform = translation({std::numeric_limits<double>::infinity(), 0.0, 0.0}); }
  if (transform != Mat4d(1.0))
    CHECK_THROWS_AS(rt::flatten_scene(one_child_scene(transform, oblique_triangle())), rt::InputError);
}

TEST_CASE("flatten rejects a model under a singular parent", "[flatten]") {
  rt::Scene scene = one_child_scene(Mat4d(1.0), oblique_triangle());
  REQUIRE_NOTHROW(rt::flatten_scene(scene));
  scene.nodes[0].parent_from_node = scaling({1.0, 1.0, 0.0});
  CHECK_THROWS_AS(rt::flatten_scene(scene), rt::InputError);
}

TEST_CASE("flattened positions keep a spare slot for Embree's 16-byte loads", "[flatten]") {
  for (int copies : {1, 2, 7, 64}) {
    rt::Scene scene = rt_test::make_scene({});
    scene.materials.resize(1);
    for (int i = 0; i < copies; ++i)
      scene.nodes[0].models.push_back({std::make_shared<const rt::TriangleMesh>(oblique_triangle()), 0});
    const rt::FlatScene flat = rt::flatten_scene(scene);
    INFO(copies << " triangles");
    REQUIRE(flat.positions.size() == static_cast<std::size_t>(3 * copies));
    CHECK(flat.positions.capacity() > flat.positions.size());
  }
}

TEST_CASE("flattening a scene without geometry gives empty buffers", "[flatten]") {
  rt::Scene scene = rt_test::make_scene({});  // a root node, no models
  const rt::FlatScene flat = rt::flatten_scene(scene);
  CHECK(flat.positions.empty());
  CHECK(flat.normals.empty());
  CHECK(flat.triangles.empty());
  CHECK(flat.material_ids.empty());
  CHECK(flat.positions.capacity() > flat.positions.size());
}
