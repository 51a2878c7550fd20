#include "export.h"

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "rt/accel/accel.h"
#include "rt/app/scene_options.h"
#include "rt/core/error.h"
#include "rt/io/load_scene.h"
#include "rt/render/camera.h"

namespace rt::perf {

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;

static_assert(std::endian::native == std::endian::little, "the PLY files are written as the machine stores floats");

struct ExportArgs {
  std::string scene;  // empty: the built-in default scene
  std::string out;
  std::optional<int> width, height, max_depth;
  int sphere_tessellation = 0;
  GltfOptions gltf;
  SceneOptions scene_options;
};

Json to_json(const Vec3d& v) { return Json::array({v.x, v.y, v.z}); }
Json to_json(const Color& c) { return Json::array({double(c.r), double(c.g), double(c.b)}); }

// Row-major rows of a (column-major) glm matrix, as Mitsuba's to_world takes them.
Json rows_of(const Mat4d& m) {
  Json rows = Json::array();
  for (int row = 0; row < 4; ++row) rows.push_back(Json::array({m[0][row], m[1][row], m[2][row], m[3][row]}));
  return rows;
}

Json light_json(const Light& light) {
  Json json;
  json["type"] = light.is_directional() ? "directional" : light.is_spot() ? "spot" : "point";
  json["position"] = Json::array({light.position.x, light.position.y, light.position.z, light.position.w});
  json["color"] = to_json(light.color);
  json["attenuation"] = to_json(light.attenuation);
  json["spot_direction"] = to_json(light.spot_direction);
  json["spot_cos_inner"] = light.spot_cos_inner;
  json["spot_cos_outer"] = light.spot_cos_outer;
  return json;
}

Json texture_json(const Texture& texture) { return texture.empty() ? Json(nullptr) : Json(texture.path); }

// The scene as `rt render` loads it: file or built-in default, command-line image size and depth,
// then the scene flags, validated.
Scene load_as_rt_render(const ExportArgs& args, LoadReport& report) {
  ImageOverrides image;
  image.width = args.width;
  image.height = args.height;
  image.max_depth = args.max_depth;
  return load_scene_for_command(args.scene, args.gltf, image, args.scene_options,
                                report);
}

// Camera rays through pixel centres (rt's --spp 1) that hit a triangle from behind, i.e. where
// the ray direction points the way the geometric normal (p1 - p0) x (p2 - p0) does, on a
// material whose back faces are not flipped (check-mitsuba wraps flipped ones in Mitsuba's
// `twosided`) and not glass. rt shades such hits with their own normals (unflipped) or sees
// through them (culled); a one-sided BSDF (Mitsuba's diffuse) renders them black.
std::uint64_t count_back_face_hits(const Scene& scene, const FlatScene& flat) {
  if (flat.triangles.empty()) return 0;
  const std::unique_ptr<Accel> accel = build_accel(AccelKind::embree, flat);
  const CameraFrame frame = make_camera_frame(scene.camera, scene.settings.width, scene.settings.height, scene.source);
  std::uint64_t back = 0;
  for (int j = 0; j < scene.settings.height; ++j)
    for (int i = 0; i < scene.settings.width; ++i) {
      const Ray ray = ray_through_pixel(frame, i, j);
      const Hit hit = accel->intersect(ray);
      if (!hit.found() || flat.is_sphere(hit.primitive)) continue;
      const Material& material = scene.materials[flat.material_of(hit.primitive)];
      if (material.back_face == BackFace::flipped || material.is_dielectric()) continue;
      const Vec3u tri = flat.triangles[hit.primitive];
      const Vec3d p0(flat.positions[tri.x]), p1(flat.positions[tri.y]), p2(flat.positions[tri.z]);
      if (glm::dot(glm::cross(p1 - p0, p2 - p0), Vec3d(ray.direction)) > 0.0) ++back;
    }
  return back;
}

void write_text_file(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  out.close();
  if (!out) throw RuntimeError(fmt::format("cannot write {}: {}", path.string(), std::strerror(errno)));
}

int run_export(const ExportArgs& args) {
  LoadReport report;
  const Scene scene = load_as_rt_render(args, report);
  FlattenOptions flatten_options;
  flatten_options.sphere_tessellation = args.sphere_tessellation;
  const FlatScene flat = flatten_scene(scene, flatten_options);

  const fs::path out(args.out);
  std::error_code error;
  fs::create_directories(out, error);
  if (error || !fs::is_directory(out))
    throw RuntimeError(fmt::format("--out {}: cannot create the directory{}", args.out,
                                   error ? ": " + error.message() : ""));

  std::vector<std::size_t> spheres_per_material(scene.materials.size(), 0);
  Json spheres = Json::array();
  for (const FlatSphere& sphere : flat.spheres) {
    ++spheres_per_material[sphere.material];
    spheres.push_back({{"material", sphere.material}, {"to_world", rows_of(sphere.world_from_object)}});
  }
  std::vector<std::size_t> triangles_per_material(scene.materials.size(), 0);
  for (const std::uint32_t id : flat.material_ids) ++triangles_per_material[id];

  Json materials = Json::array();
  for (std::uint32_t m = 0; m < scene.materials.size(); ++m) {
    const Material& material = scene.materials[m];
    Json json;
    json["name"] = material.name;
    json["ambient"] = to_json(material.ambient);
    json["diffuse"] = to_json(material.diffuse);
    json["specular"] = to_json(material.specular);
    json["emission"] = to_json(material.emission);
    json["shininess"] = material.shininess;
    json["reflective"] = material.reflective ? to_json(*material.reflective) : Json(nullptr);
    json["emits_light"] = material.emits_light;
    json["transmission"] = to_json(material.transmission);
    json["ior"] = material.ior;
    json["thin_walled"] = material.thin_walled;
    json["attenuation_color"] = to_json(material.attenuation_color);
    json["back_face"] = material.back_face == BackFace::flipped ? "flipped"
                        : material.back_face == BackFace::culled ? "culled"
                                                                 : "unflipped";
    json["alpha"] = material.has_alpha() ? Json(material.alpha_mode == AlphaMode::mask ? "mask" : "blend") : Json(nullptr);
    json["attenuation_distance"] =
        std::isfinite(material.attenuation_distance) ? Json(material.attenuation_distance) : Json(nullptr);
    json["diffuse_texture"] = texture_json(material.diffuse_texture);
    json["emission_texture"] = texture_json(material.emission_texture);
    json["triangles"] = triangles_per_material[m];
    json["spheres"] = spheres_per_material[m];
    json["mesh"] = nullptr;
    if (triangles_per_material[m] > 0) {
      const std::string name = fmt::format("mesh-{}.ply", m);
      write_material_ply(flat, m, (out / name).string(),
                         fmt::format("rt-perf export-mitsuba: material {} of {}, world space", m, scene.source));
      json["mesh"] = name;
    }
    materials.push_back(std::move(json));
  }

  Json notices = Json::array();
  for (const std::string& notice : scene.notices) notices.push_back("notice: " + notice);
  for (const std::string& notice : scene_notices(args.scene_options, report, scene)) notices.push_back(notice);

  Json json;
  json["format"] = "rt-mitsuba-export 1";
  json["source"] = scene.source;
  json["image"] = {{"width", scene.settings.width}, {"height", scene.settings.height}};
  json["camera"] = {{"eye", to_json(scene.camera.eye)},
                    {"target", to_json(scene.camera.target)},
                    {"up", to_json(scene.camera.up)},
                    {"fovy", scene.camera.fovy_degrees}};
  json["background"] = to_json(scene.settings.background);
  json["max_depth"] = scene.settings.max_depth;
  json["lights"] = Json::array();
  for (const Light& light : scene.lights) json["lights"].push_back(light_json(light));
  json["headlight"] = report.default_lights_added && !args.scene_options.lights_given();
  json["materials"] = std::move(materials);
  json["spheres"] = std::move(spheres);
  const Bounds3d bounds = flat_bounds(flat);  // world space; null when there is no geometry
  json["bounds"] = bounds.empty() ? Json(nullptr) : Json{{"lower", to_json(bounds.lo)}, {"upper", to_json(bounds.hi)}};
  json["triangles"] = flat.triangle_count();
  json["degenerate_triangles_dropped"] = flat.degenerate_triangles_dropped;
  json["camera_rays"] = std::uint64_t(scene.settings.width) * std::uint64_t(scene.settings.height);
  json["camera_back_face_hits"] = count_back_face_hits(scene, flat);
  json["notices"] = std::move(notices);
  write_text_file(out / "scene.json", json.dump(2) + "\n");
  return 0;
}

}  // namespace

std::size_t write_material_ply(const FlatScene& flat, std::uint32_t material, const std::string& path,
                               std::string comment) {
  std::replace_if(comment.begin(), comment.end(), [](char c) { return c == '\n' || c == '\r'; }, ' ');
  // Local vertex numbers in order of first use; -1: not used by this material.
  std::vector<std::int64_t> local(flat.positions.size(), -1);
  std::vector<std::uint32_t> vertices;  // global index of each local vertex
  std::vector<std::int32_t> faces;      // three local indices per triangle
  for (std::size_t t = 0; t < flat.triangles.size(); ++t) {
    if (flat.material_ids[t] != material) continue;
    for (const std::uint32_t v : {flat.triangles[t].x, flat.triangles[t].y, flat.triangles[t].z}) {
      if (local[v] < 0) {
        if (vertices.size() >= std::size_t(std::numeric_limits<std::int32_t>::max()))
          throw RuntimeError(fmt::format("{}: more vertices than a PLY int index holds", path));
        local[v] = std::int64_t(vertices.size());
        vertices.push_back(v);
      }
      faces.push_back(std::int32_t(local[v]));
    }
  }

  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << "ply\nformat binary_little_endian 1.0\ncomment " << comment << "\n"
      << "element vertex " << vertices.size() << "\n"
      << "property float x\nproperty float y\nproperty float z\n"
      << "property float nx\nproperty float ny\nproperty float nz\n"
      << "element face " << faces.size() / 3 << "\n"
      << "property list uchar int vertex_indices\nend_header\n";
  for (const std::uint32_t v : vertices) {
    const float record[6] = {flat.positions[v].x, flat.positions[v].y, flat.positions[v].z,
                             flat.normals[v].x,   flat.normals[v].y,   flat.normals[v].z};
    out.write(reinterpret_cast<const char*>(record), sizeof record);
  }
  for (std::size_t f = 0; f < faces.size(); f += 3) {
    const unsigned char count = 3;
    out.write(reinterpret_cast<const char*>(&count), 1);
    out.write(reinterpret_cast<const char*>(&faces[f]), 3 * sizeof(std::int32_t));
  }
  out.close();
  if (!out) throw RuntimeError(fmt::format("cannot write {}: {}", path, std::strerror(errno)));
  return faces.size() / 3;
}

std::function<int()> add_export_command(CLI::App& app) {
  CLI::App* command = app.add_subcommand(
      "export-mitsuba",
      "Write a scene as rt render loads it (flags included) for tools/check-mitsuba: DIR/scene.json (camera, "
      "lights, materials, spheres) and DIR/mesh-<material>.ply (world-space triangles per material)");
  auto args = std::make_shared<ExportArgs>();
  command->add_option("scene", args->scene, "Scene file (.json, .test, .gltf, .glb, .obj); default: the built-in scene");
  command->add_option("--out", args->out, "Directory to write into (created if missing)")->required();
  command->add_option("--width", args->width, "Image width in pixels (as rt render --width)")
      ->check(CLI::Range(1, kMaxImageSide));
  command->add_option("--height", args->height, "Image height in pixels (as rt render --height)")
      ->check(CLI::Range(1, kMaxImageSide));
  command->add_option("--max-depth", args->max_depth, "Reflection depth (as rt render --max-depth)")
      ->check(CLI::Range(0, kMaxReflectionDepth));
  command->add_option("--sphere-tessellation", args->sphere_tessellation,
                      "Tessellate spheres into N slices (as rt render --sphere-tessellation; 0 keeps them exact, "
                      "1 and 2 are refused when flattening)")
      ->check(CLI::NonNegativeNumber);
  command->add_option("--gltf-scene", args->gltf.scene, "glTF only: index of the scene (as rt render)")
      ->check(CLI::NonNegativeNumber);
  command->add_option("--camera", args->gltf.camera, "glTF only: camera name or index (as rt render)");
  add_scene_options(*command, args->scene_options);
  return [args] { return run_export(*args); };
}

}  // namespace rt::perf
