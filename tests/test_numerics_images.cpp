// Numerical robustness, part 4: whole images.
//
// A 200 x 200 ground plane (two triangles) lit by a directional light 2 degrees above the horizon,
// diffuse only, seen from straight above. Its correct image is one constant colour
//   L * Cd * sin(2 deg)
// (no shadow acne, no holes along the diagonal). A 20 x 20 x 20 box standing on the plane must
// still shadow the plane right at its base on the side away from the light (no light leaking
// under it). Rendered with rt::render_image at the origin and translated by 1e3 and 1e5 (camera,
// geometry and light together). Embree robust + robust offset and the reference + robust offset
// are asserted; the fixed offset fixed:1e-4 and Embree with robust mode off are printed.
//
// Regenerate the table with build/release/tests/rt_tests "[numerics]~[slow]".

#include "catch.h"

#include <cmath>
#include <cstdint>
#include <iostream>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "numerics_util.h"
#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"
#include "rt/io/image_io.h"
#include "rt/render/ray_offset.h"
#include "rt/render/render.h"
#include "rt/scene/shapes.h"
#include "test_util.h"

namespace {

using namespace rt_numerics;

constexpr int kWidth = 160, kHeight = 120;
constexpr double kFovyDegrees = 45.0;
constexpr double kEyeHeight = 100.0;
constexpr double kHalfPlane = 100.0;
constexpr double kElevationDegrees = 2.0;
constexpr float kLightIntensity = 20.0f;
constexpr float kDiffuse = 0.8f;
// The box: x in [10, 30], y in [0, 20], z in [-10, 10], on the plane y = 0. The light comes from
// +x, so the box's shadow falls towards -x from its face x = 10, which the camera (above x = 0)
// sees together with the plane in front of it.
constexpr double kBoxX0 = 10.0, kBoxX1 = 30.0, kBoxHeight = 20.0, kBoxHalfZ = 10.0;

// Expected byte of a lit, upward-facing surface: floor(255 * L * Cd * sin(2 deg)) =
// floor(255 * 20 * 0.8 * 0.0348995) = floor(142.39) = 142. Worked out in double from the float32
// diffuse the scene stores.
int lit_byte() {
  const double value = double(kLightIntensity) * double(kDiffuse) * std::sin(kElevationDegrees * std::numbers::pi / 180.0);
  return static_cast<int>(std::floor(255.0 * value));
}

rt::Scene ground_scene(const Vec3d& offset, bool with_box) {
  rt::Scene scene = rt_test::make_scene({});
  scene.source = "<numerics image test>";
  rt::Material ground;
  ground.diffuse = rt::Color(kDiffuse);
  scene.materials.push_back(ground);
  const double h = kHalfPlane;
  rt::TriangleMesh plane = rt_test::make_flat_mesh({{Vec3f(Vec3d(-h, 0, -h)), Vec3f(Vec3d(-h, 0, h)), Vec3f(Vec3d(h, 0, h))},
                                                    {Vec3f(Vec3d(-h, 0, -h)), Vec3f(Vec3d(h, 0, h)), Vec3f(Vec3d(h, 0, -h))}});
  rt::Node node;
  node.parent_from_node = glm::translate(rt::Mat4d(1.0), offset);
  node.models.push_back({std::make_shared<const rt::TriangleMesh>(plane), 0});
  if (with_box) {
    rt::Node box;
    box.parent_from_node = glm::translate(rt::Mat4d(1.0), Vec3d(0.5 * (kBoxX0 + kBoxX1), 0.5 * kBoxHeight, 0.0)) *
                           glm::scale(rt::Mat4d(1.0), Vec3d(kBoxX1 - kBoxX0, kBoxHeight, 2.0 * kBoxHalfZ));
    box.models.push_back({std::make_shared<const rt::TriangleMesh>(rt::make_cube_mesh()), 0});
    node.children.push_back(2);
    scene.nodes[0].children.push_back(1);
    scene.nodes.push_back(node);
    scene.nodes.push_back(box);
  } else {
    scene.nodes[0].children.push_back(1);
    scene.nodes.push_back(node);
  }
  const double elevation = kElevationDegrees * std::numbers::pi / 180.0;
  rt::Light light;
  light.position = rt::Vec4d(std::cos(elevation), std::sin(elevation), 0.0, 0.0);  // towards the light
  light.color = rt::Color(kLightIntensity);
  scene.lights.push_back(light);
  scene.camera.eye = offset + Vec3d(0.0, kEyeHeight, 0.0);
  scene.camera.target = offset;
  scene.camera.up = Vec3d(0.0, 0.0, -1.0);
  scene.camera.fovy_degrees = kFovyDegrees;
  scene.settings.width = kWidth;
  scene.settings.height = kHeight;
  scene.settings.max_depth = 0;
  return scene;
}

// What the pixel's centre ray sees, worked out independently of the renderer: the camera looks down
// -y with image right = +x and image up = -z (frame u = up x w = (1, 0, 0), v = w x u = (0, 0, -1)),
// so pixel (i, j) looks along (alpha * aspect * tan(fovy / 2), -1, -beta * tan(fovy / 2)) with
// alpha = 2 (i + 0.5) / W - 1, beta = 1 - 2 (j + 0.5) / H. Returns -1 when the ray passes within
// kMargin of a boundary between differently lit surfaces (pixels excluded from the comparison),
// else the expected byte; `contact` is set for plane pixels in the box's shadow within two pixel
// footprints of its base.
constexpr double kMargin = 0.01;  // world units; a pixel is ~0.69 wide on the plane
int expected_byte(int i, int j, bool with_box, bool& contact) {
  contact = false;
  const double tan_half = std::tan(kFovyDegrees * std::numbers::pi / 360.0), aspect = double(kWidth) / kHeight;
  const double alpha = 2.0 * (i + 0.5) / kWidth - 1.0, beta = 1.0 - 2.0 * (j + 0.5) / kHeight;
  const double dx = alpha * aspect * tan_half, dz = -beta * tan_half;  // per unit of descent
  if (with_box) {
    // Top face y = 20: lit like the plane (its shadow ray leaves upwards-sideways, unobstructed).
    const double tx = (kEyeHeight - kBoxHeight) * dx, tz = (kEyeHeight - kBoxHeight) * dz;
    const double top_inside = std::min({tx - kBoxX0, kBoxX1 - tx, kBoxHalfZ - std::abs(tz)});
    if (std::abs(top_inside) < kMargin) return -1;
    if (top_inside > 0.0) return lit_byte();
    // Face x = 10 (normal -x, facing away from the light): black. Reached at descent 10 / dx.
    if (dx > 0.0) {
      const double descent = kBoxX0 / dx, y = kEyeHeight - descent, z = descent * dz;
      const double face_inside = std::min({kBoxHeight - y, kBoxHalfZ - std::abs(z)});  // y >= 0 borders the shadow
      if (y >= 0.0 && std::abs(face_inside) < kMargin) return -1;
      if (y >= 0.0 && face_inside > 0.0) return 0;
    }
  }
  // The plane y = 0 at (x, z).
  const double x = kEyeHeight * dx, z = kEyeHeight * dz;
  if (!with_box) return lit_byte();
  // In the box's shadow: |z| < 10 and x < 10 (the shadow reaches 20 / tan(2 deg) = 573 units,
  // beyond the frame). x >= 10 with |z| < 10 is under the box, hidden.
  if (std::abs(std::abs(z) - kBoxHalfZ) < kMargin) return -1;
  if (std::abs(z) < kBoxHalfZ && x < kBoxX0) {
    const double footprint = 2.0 * kEyeHeight * tan_half / kHeight;
    contact = kBoxX0 - x < 2.0 * footprint;
    return 0;
  }
  return lit_byte();
}

struct ImageCounts {
  std::size_t checked = 0, failing = 0, contact = 0, contact_failing = 0;
};

ImageCounts compare(const rt::Image& image, bool with_box) {
  const std::vector<std::uint8_t> bytes = rt::to_rgb8(image);
  ImageCounts counts;
  for (int j = 0; j < kHeight; ++j)
    for (int i = 0; i < kWidth; ++i) {
      bool contact = false;
      const int expected = expected_byte(i, j, with_box, contact);
      if (expected < 0) continue;
      ++counts.checked;
      bool off = false;
      for (int c = 0; c < 3; ++c)
        off = off || std::abs(int(bytes[3 * (std::size_t(j) * kWidth + i) + c]) - expected) > 1;
      counts.failing += off;
      counts.contact += contact;
      counts.contact_failing += contact && off;
    }
  return counts;
}

struct RenderConfig {
  const char* name;
  Path path;
  const char* offset;
  bool asserted;
};
const RenderConfig kRenderConfigs[] = {
    {"Embree robust + robust offset (default)", Path::embree_robust, "robust", true},
    {"reference + robust offset", Path::reference, "robust", true},
    {"Embree + watertight kernel + robust offset", Path::embree_exact, "robust", true},
    {"Embree robust + fixed:1e-4", Path::embree_robust, "fixed:1e-4", false},
    {"Embree default (robust off) + robust offset", Path::embree_default, "robust", false},
    {"Embree default (robust off) + fixed:1e-4", Path::embree_default, "fixed:1e-4", false},
};

void run_images(bool with_box, const std::vector<Vec3d>& offsets) {
  std::cout << "\n### " << (with_box ? "Box on a ground plane" : "Ground plane")
            << ", light at 2 degrees, seen from above (" << kWidth << "x" << kHeight
            << "): pixels off the expected byte by more than 1\n\n"
            << "| placement | configuration | pixels checked | failing pixels |"
            << (with_box ? " shadowed pixels at the box's base | of which lit (leaking) |" : "") << "\n"
            << (with_box ? "|---|---|---|---|---|---|\n" : "|---|---|---|---|\n");
  for (const Vec3d& offset : offsets) {
    const rt::Scene scene = ground_scene(offset, with_box);
    const rt::FlatScene flat = rt::flatten_scene(scene);
    REQUIRE(flat.degenerate_triangles_dropped == 0);
    for (const RenderConfig& config : kRenderConfigs) {
      const std::unique_ptr<rt::Accel> accel = build(config.path, flat);
      rt::RenderOptions options;
      options.ray_offset = rt::parse_ray_offset(config.offset);
      const rt::RenderResult result = rt::render_image(scene, flat, *accel, options);
      const ImageCounts counts = compare(result.image, with_box);
      std::cout << "| (" << offset.x << ", " << offset.y << ", " << offset.z << ") | " << config.name << " | "
                << counts.checked << " | " << counts.failing << " |";
      if (with_box) std::cout << " " << counts.contact << " | " << counts.contact_failing << " |";
      std::cout << "\n";
      INFO(config.name << " at offset " << offset.x);
      CHECK(counts.checked > std::size_t(kWidth * kHeight * 9 / 10));  // few pixels excluded at boundaries
      if (with_box) CHECK(counts.contact > 40);  // two columns of plane pixels along the 20-unit base
      if (config.asserted) {
        CHECK(counts.failing == 0);
        CHECK(counts.contact_failing == 0);
      }
    }
  }
  std::cout << std::endl;
}

}  // namespace

TEST_CASE("a ground plane lit at 2 degrees renders as one flat colour, also far from the origin", "[numerics]") {
  REQUIRE(lit_byte() == 142);  // 255 * 20 * 0.8 * sin(2 deg) = 142.39
  run_images(false, {Vec3d(0.0), Vec3d(1e3), Vec3d(1e5)});
}

TEST_CASE("a box on the plane shadows it right up to its base, also far from the origin", "[numerics]") {
  run_images(true, {Vec3d(0.0), Vec3d(1e5)});
}
