#include "rt/io/load_scene.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>

#include <fmt/format.h>
#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>

#include "rt/core/error.h"
#include "rt/io/load_obj.h"
#include "rt/io/load_test.h"
#include "rt/scene/shapes.h"

namespace rt {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;  // keeps file order: materials and nodes are numbered as written

namespace {

// Default tessellation of "sphere" geometry: 2 * 32 * 15 = 960 triangles.
constexpr int kDefaultSphereSlices = 32;
constexpr int kDefaultSphereStacks = 16;
// Deepest node nesting read (levels below /nodes); deeper files are refused, not recursed into.
// AddressSanitizer frames overflow the 8 MiB main stack near 1,000 levels; 256 leaves a margin.
constexpr std::size_t kMaxNodeDepth = 256;

// Walks a parsed document, naming every value by its JSON pointer (e.g. /nodes/2/translate) so
// that each error can say exactly where it is.
class SceneReader {
 public:
  SceneReader(std::string path) : path_(std::move(path)), directory_(fs::path(path_).parent_path()) {}

  Scene read(const json& document);

 private:
  [[noreturn]] void fail(const std::string& where, const std::string& reason) const {
    throw InputError(path_, where, reason);
  }

  void check_keys(const json& object, const std::string& where, std::initializer_list<const char*> allowed) const;
  const json& require_object(const json& value, const std::string& where) const;
  const json& require_array(const json& value, const std::string& where) const;
  double read_number(const json& value, const std::string& where) const;
  int read_int(const json& value, const std::string& where, int min_value, int max_value = 1'000'000'000) const;
  std::string read_string(const json& value, const std::string& where) const;
  Vec3d read_vec3(const json& value, const std::string& where) const;
  Color read_color(const json& value, const std::string& where) const;

  void read_settings(const json& document, Scene& scene) const;
  DisplayTransform read_display(const json& value, const std::string& where) const;
  Camera read_camera(const json& value, const std::string& where) const;
  Material read_material(const json& value, const std::string& where, const std::string& name) const;
  Light read_light(const json& value, const std::string& where) const;
  // The geometry of a model: Model::mesh or Model::sphere set, the material left to the caller.
  Model read_geometry(const json& value, const std::string& where);
  Mat4d read_transform(const json& node, const std::string& where) const;
  // `depth`: ancestors of the node, the root's children having none. Nodes are read recursively,
  // so the depth is capped (kMaxNodeDepth) to keep a hostile file from exhausting the stack.
  std::uint32_t read_node(const json& value, const std::string& where, Scene& scene, std::size_t depth);

  std::string path_;
  fs::path directory_;
  std::map<std::string, std::uint32_t> material_index_;
  std::map<std::string, Model> named_geometry_;
  std::map<std::string, std::shared_ptr<const TriangleMesh>> obj_cache_;
};

std::string type_name(const json& value) {
  if (value.is_number()) return "a number";
  if (value.is_string()) return "a string";
  if (value.is_array()) return "an array";
  if (value.is_object()) return "an object";
  if (value.is_boolean()) return "a boolean";
  return "null";
}

std::string child(const std::string& where, const std::string& key) { return where + "/" + key; }
std::string child(const std::string& where, std::size_t index) { return where + "/" + std::to_string(index); }

void SceneReader::check_keys(const json& object, const std::string& where,
                             std::initializer_list<const char*> allowed) const {
  for (const auto& [key, value] : object.items()) {
    bool known = false;
    for (const char* name : allowed) known = known || key == name;
    if (!known) {
      std::string list;
      for (const char* name : allowed) list += (list.empty() ? "" : ", ") + std::string(name);
      fail(child(where, key), fmt::format("unknown key '{}' (expected one of: {})", key, list));
    }
  }
}

const json& SceneReader::require_object(const json& value, const std::string& where) const {
  if (!value.is_object()) fail(where, "expected an object, got " + type_name(value));
  return value;
}

const json& SceneReader::require_array(const json& value, const std::string& where) const {
  if (!value.is_array()) fail(where, "expected an array, got " + type_name(value));
  return value;
}

double SceneReader::read_number(const json& value, const std::string& where) const {
  if (!value.is_number()) fail(where, "expected a number, got " + type_name(value));
  const double number = value.get<double>();
  if (!std::isfinite(number)) fail(where, "number is not finite");
  return number;
}

int SceneReader::read_int(const json& value, const std::string& where, int min_value, int max_value) const {
  const double number = read_number(value, where);
  if (number != std::floor(number)) fail(where, fmt::format("{} is not an integer", number));
  if (number < min_value || number > max_value)
    fail(where, fmt::format("{} is outside {}..{}", number, min_value, max_value));
  return static_cast<int>(number);
}

std::string SceneReader::read_string(const json& value, const std::string& where) const {
  if (!value.is_string()) fail(where, "expected a string, got " + type_name(value));
  return value.get<std::string>();
}

Vec3d SceneReader::read_vec3(const json& value, const std::string& where) const {
  if (!value.is_array() || value.size() != 3) fail(where, "expected an array of 3 numbers");
  return {read_number(value[0], child(where, 0)), read_number(value[1], child(where, 1)),
          read_number(value[2], child(where, 2))};
}

Color SceneReader::read_color(const json& value, const std::string& where) const {
  const Vec3d rgb = value.is_number() ? Vec3d(read_number(value, where)) : read_vec3(value, where);
  if (rgb.r < 0 || rgb.g < 0 || rgb.b < 0) fail(where, "colour components must be >= 0");
  return Color(rgb);
}

void SceneReader::read_settings(const json& document, Scene& scene) const {
  RenderSettings& settings = scene.settings;
  if (document.contains("image")) {
    const json& image = require_object(document["image"], "/image");
    check_keys(image, "/image", {"width", "height"});
    if (image.contains("width")) settings.width = read_int(image["width"], "/image/width", 1, kMaxImageSide);
    if (image.contains("height")) settings.height = read_int(image["height"], "/image/height", 1, kMaxImageSide);
  }
  if (document.contains("max_depth")) settings.max_depth = read_int(document["max_depth"], "/max_depth", 0, kMaxReflectionDepth);
  if (document.contains("background")) settings.background = read_color(document["background"], "/background");
  if (document.contains("output")) settings.output = read_string(document["output"], "/output");
  if (document.contains("display")) settings.display = read_display(document["display"], "/display");
}

// "display": "linear" or "srgb", or { "encoding": ..., "exposure": EV, "tonemap": ... }
// (docs/display.md).
DisplayTransform SceneReader::read_display(const json& value, const std::string& where) const {
  DisplayTransform display;
  const auto encoding = [&](const json& value_at, const std::string& at) {
    const std::string name = read_string(value_at, at);
    try {
      return parse_display_encoding(name);
    } catch (const InputError&) {
      fail(at, fmt::format("'{}' is not linear or srgb", name));
    }
  };
  if (value.is_string()) {
    display.encoding = encoding(value, where);
    return display;
  }
  require_object(value, where);
  check_keys(value, where, {"encoding", "exposure", "tonemap"});
  if (value.contains("encoding")) display.encoding = encoding(value["encoding"], child(where, "encoding"));
  if (value.contains("exposure")) {
    display.exposure_ev = read_number(value["exposure"], child(where, "exposure"));
    if (!(std::abs(display.exposure_ev) <= 64.0)) fail(child(where, "exposure"), "exposure must be within -64..64 EV");
  }
  if (value.contains("tonemap")) {
    const std::string name = read_string(value["tonemap"], child(where, "tonemap"));
    try {
      display.tonemap = parse_tonemap(name);
    } catch (const InputError&) {
      fail(child(where, "tonemap"), fmt::format("'{}' is not none, aces or pbr-neutral", name));
    }
  }
  return display;
}

Camera SceneReader::read_camera(const json& value, const std::string& where) const {
  require_object(value, where);
  check_keys(value, where, {"eye", "target", "up", "fovy"});
  Camera camera;
  for (const char* key : {"eye", "target", "fovy"})
    if (!value.contains(key)) fail(where, fmt::format("missing key '{}'", key));
  camera.eye = read_vec3(value["eye"], child(where, "eye"));
  camera.target = read_vec3(value["target"], child(where, "target"));
  if (value.contains("up")) camera.up = read_vec3(value["up"], child(where, "up"));
  camera.fovy_degrees = read_number(value["fovy"], child(where, "fovy"));
  if (auto problem = find_camera_problem(camera)) fail(child(where, problem->field), problem->reason);
  return camera;
}

Material SceneReader::read_material(const json& value, const std::string& where, const std::string& name) const {
  require_object(value, where);
  check_keys(value, where, {"ambient", "diffuse", "specular", "emission", "shininess", "emitter", "transmission", "ior",
                            "thin", "attenuation_color", "attenuation_distance", "alpha", "alpha_mode", "alpha_cutoff", "back_face"});
  Material material;
  material.name = name;
  if (value.contains("ambient")) material.ambient = read_color(value["ambient"], child(where, "ambient"));
  if (value.contains("diffuse")) material.diffuse = read_color(value["diffuse"], child(where, "diffuse"));
  if (value.contains("specular")) material.specular = read_color(value["specular"], child(where, "specular"));
  if (value.contains("emission")) material.emission = read_color(value["emission"], child(where, "emission"));
  if (value.contains("emitter")) {
    // true: `emission` is radiance leaving the front side, and an area light (docs/area-lights.md).
    if (!value["emitter"].is_boolean())
      fail(child(where, "emitter"), fmt::format("expected true or false, got {}", type_name(value["emitter"])));
    material.emits_light = value["emitter"].get<bool>();
  }
  if (value.contains("shininess")) {
    const double shininess = read_number(value["shininess"], child(where, "shininess"));
    if (shininess < 0) fail(child(where, "shininess"), "shininess must be >= 0");
    material.shininess = static_cast<float>(shininess);
  }
  // A dielectric (docs/json-scene-format.md): transmission, ior, thin, attenuation_*.
  if (value.contains("transmission"))
    material.transmission = read_color(value["transmission"], child(where, "transmission"));
  const bool dielectric_key = value.contains("ior") || value.contains("thin") || value.contains("attenuation_color") ||
                              value.contains("attenuation_distance");
  if (dielectric_key && !material.is_dielectric())
    fail(where, "ior, thin and attenuation_* describe glass: give a non-black \"transmission\" too");
  if (value.contains("ior")) {
    const double ior = read_number(value["ior"], child(where, "ior"));
    if (!(ior >= 1.0 && ior <= 10.0)) fail(child(where, "ior"), fmt::format("ior {} is outside [1, 10]", ior));
    material.ior = static_cast<float>(ior);
  }
  if (value.contains("thin")) {
    if (!value["thin"].is_boolean())
      fail(child(where, "thin"), fmt::format("expected true or false, got {}", type_name(value["thin"])));
    material.thin_walled = value["thin"].get<bool>();
  }
  if (value.contains("attenuation_color")) {
    material.attenuation_color = read_color(value["attenuation_color"], child(where, "attenuation_color"));
    if (material.attenuation_color.r > 1 || material.attenuation_color.g > 1 || material.attenuation_color.b > 1)
      fail(child(where, "attenuation_color"), "components must be <= 1 (the colour left after attenuation_distance)");
  }
  if (value.contains("attenuation_distance")) {
    const double distance = read_number(value["attenuation_distance"], child(where, "attenuation_distance"));
    if (!(distance > 0.0)) fail(child(where, "attenuation_distance"), "attenuation_distance must be > 0");
    material.attenuation_distance = static_cast<float>(distance);
  }
  // Alpha (docs/alpha.md): "alpha" in [0, 1], seen-through as "blend" (the default once "alpha"
  // is given) or cut out below "alpha_cutoff" as "mask".
  if (value.contains("alpha")) {
    const double alpha = read_number(value["alpha"], child(where, "alpha"));
    if (!(alpha >= 0.0 && alpha <= 1.0)) fail(child(where, "alpha"), fmt::format("alpha {} is outside [0, 1]", alpha));
    material.alpha = static_cast<float>(alpha);
    material.alpha_mode = AlphaMode::blend;
  }
  if (value.contains("alpha_mode")) {
    const std::string mode = read_string(value["alpha_mode"], child(where, "alpha_mode"));
    if (mode == "opaque") material.alpha_mode = AlphaMode::opaque;
    else if (mode == "mask") material.alpha_mode = AlphaMode::mask;
    else if (mode == "blend") material.alpha_mode = AlphaMode::blend;
    else fail(child(where, "alpha_mode"), fmt::format("'{}' is not opaque, mask or blend", mode));
  }
  if (value.contains("alpha_cutoff")) {
    const double cutoff = read_number(value["alpha_cutoff"], child(where, "alpha_cutoff"));
    if (!(cutoff >= 0.0 && cutoff <= 1.0)) fail(child(where, "alpha_cutoff"), fmt::format("alpha_cutoff {} is outside [0, 1]", cutoff));
    material.alpha_cutoff = static_cast<float>(cutoff);
  }
  if (value.contains("back_face")) {  // docs/scene-formats.md, "Front and back faces"
    const std::string mode = read_string(value["back_face"], child(where, "back_face"));
    if (mode == "unflipped") material.back_face = BackFace::unflipped;
    else if (mode == "flipped") material.back_face = BackFace::flipped;
    else if (mode == "culled") material.back_face = BackFace::culled;
    else fail(child(where, "back_face"), fmt::format("'{}' is not unflipped, flipped or culled", mode));
  }
  return material;
}

Light SceneReader::read_light(const json& value, const std::string& where) const {
  require_object(value, where);
  if (!value.contains("type")) fail(where, "missing key 'type' (point or directional)");
  const std::string type = read_string(value["type"], child(where, "type"));
  Light light;
  if (type == "point") {
    check_keys(value, where, {"type", "position", "color", "attenuation"});
    if (!value.contains("position")) fail(where, "missing key 'position'");
    light.position = Vec4d(read_vec3(value["position"], child(where, "position")), 1.0);
    if (value.contains("attenuation")) {
      light.attenuation = read_vec3(value["attenuation"], child(where, "attenuation"));
      if (light.attenuation.x < 0 || light.attenuation.y < 0 || light.attenuation.z < 0 ||
          light.attenuation == Vec3d(0.0))
        fail(child(where, "attenuation"), "attenuation coefficients must be >= 0 and not all zero");
    }
  } else if (type == "directional") {
    check_keys(value, where, {"type", "direction", "color"});
    if (!value.contains("direction")) fail(where, "missing key 'direction' (towards the light)");
    const Vec3d direction = read_vec3(value["direction"], child(where, "direction"));
    if (direction == Vec3d(0.0)) fail(child(where, "direction"), "direction is zero");
    light.position = Vec4d(direction, 0.0);
  } else {
    fail(child(where, "type"), fmt::format("unknown light type '{}' (expected point or directional)", type));
  }
  if (value.contains("color")) light.color = read_color(value["color"], child(where, "color"));
  return light;
}

Model SceneReader::read_geometry(const json& value, const std::string& where) {
  if (value.is_string()) {
    const std::string name = value.get<std::string>();
    auto it = named_geometry_.find(name);
    if (it == named_geometry_.end()) fail(where, fmt::format("no geometry named '{}' in /geometries", name));
    return it->second;
  }
  require_object(value, where);
  if (!value.contains("type")) fail(where, "missing key 'type' (cube, sphere, mesh or obj)");
  const std::string type = read_string(value["type"], child(where, "type"));
  if (type == "cube") {
    check_keys(value, where, {"type"});
    return Model{std::make_shared<const TriangleMesh>(make_cube_mesh())};
  }
  if (type == "sphere") {
    check_keys(value, where, {"type", "center", "radius", "slices", "stacks"});
    const double radius = value.contains("radius") ? read_number(value["radius"], child(where, "radius")) : 1.0;
    if (!(radius > 0)) fail(child(where, "radius"), "radius must be > 0");
    const Vec3d center = value.contains("center") ? read_vec3(value["center"], child(where, "center")) : Vec3d(0.0);
    // Exact (analytic) unless a tessellation is asked for by slices or stacks.
    if (!value.contains("slices") && !value.contains("stacks")) return Model{nullptr, 0, Sphere{center, radius}};
    const int slices = value.contains("slices") ? read_int(value["slices"], child(where, "slices"), 3, 4096)
                                                : kDefaultSphereSlices;
    const int stacks = value.contains("stacks") ? read_int(value["stacks"], child(where, "stacks"), 2, 2048)
                                                : kDefaultSphereStacks;
    TriangleMesh mesh = make_sphere_mesh(radius, slices, stacks);
    for (Vec3f& p : mesh.positions) p = Vec3f(Vec3d(p) + center);
    return Model{std::make_shared<const TriangleMesh>(std::move(mesh))};
  }
  if (type == "mesh") {
    check_keys(value, where, {"type", "positions", "triangles", "normals"});
    for (const char* key : {"positions", "triangles"})
      if (!value.contains(key)) fail(where, fmt::format("missing key '{}'", key));
    TriangleMesh mesh;
    const json& positions = require_array(value["positions"], child(where, "positions"));
    for (std::size_t i = 0; i < positions.size(); ++i)
      mesh.positions.push_back(Vec3f(read_vec3(positions[i], child(child(where, "positions"), i))));
    const json& triangles = require_array(value["triangles"], child(where, "triangles"));
    for (std::size_t i = 0; i < triangles.size(); ++i) {
      const std::string at = child(child(where, "triangles"), i);
      if (!triangles[i].is_array() || triangles[i].size() != 3) fail(at, "expected an array of 3 vertex indices");
      Vec3u tri;
      for (int k = 0; k < 3; ++k) {
        const int index = read_int(triangles[i][k], child(at, k), 0);
        if (static_cast<std::size_t>(index) >= mesh.positions.size())
          fail(child(at, k), fmt::format("vertex index {} out of range ({} positions)", index, mesh.positions.size()));
        tri[k] = static_cast<unsigned>(index);
      }
      mesh.triangles.push_back(tri);
    }
    if (value.contains("normals")) {
      const json& normals = require_array(value["normals"], child(where, "normals"));
      if (normals.size() != mesh.positions.size())
        fail(child(where, "normals"), fmt::format("{} normals for {} positions", normals.size(), mesh.positions.size()));
      for (std::size_t i = 0; i < normals.size(); ++i) {
        const Vec3d n = read_vec3(normals[i], child(child(where, "normals"), i));
        if (!(glm::length(n) > 0)) fail(child(child(where, "normals"), i), "normal is zero");
        mesh.normals.push_back(Vec3f(glm::normalize(n)));
      }
    } else {
      compute_vertex_normals(mesh);
    }
    return Model{std::make_shared<const TriangleMesh>(std::move(mesh))};
  }
  if (type == "obj") {
    check_keys(value, where, {"type", "path"});
    if (!value.contains("path")) fail(where, "missing key 'path'");
    const std::string relative = read_string(value["path"], child(where, "path"));
    const std::string resolved = (directory_ / relative).lexically_normal().string();
    std::error_code error;
    if (!fs::is_regular_file(resolved, error))
      fail(child(where, "path"), fmt::format("{} '{}' (resolved to '{}')",
                                             fs::exists(resolved, error) ? "not a regular file:" : "no such file:",
                                             relative, resolved));
    auto& cached = obj_cache_[resolved];
    if (!cached) cached = std::make_shared<const TriangleMesh>(load_obj_mesh(resolved));
    return Model{cached};
  }
  fail(child(where, "type"), fmt::format("unknown geometry type '{}' (expected cube, sphere, mesh or obj)", type));
}

Mat4d SceneReader::read_transform(const json& node, const std::string& where) const {
  const bool has_trs = node.contains("translate") || node.contains("rotate") || node.contains("scale");
  if (node.contains("matrix")) {
    if (has_trs) fail(where, "a node has either 'matrix' or translate/rotate/scale, not both");
    const std::string at = child(where, "matrix");
    const json& rows = node["matrix"];
    if (!rows.is_array() || rows.size() != 4) fail(at, "expected 4 rows of 4 numbers (row-major)");
    Mat4d m(1.0);
    for (int r = 0; r < 4; ++r) {
      if (!rows[r].is_array() || rows[r].size() != 4) fail(child(at, r), "expected a row of 4 numbers");
      for (int c = 0; c < 4; ++c) m[c][r] = read_number(rows[r][c], child(child(at, r), c));  // GLM is column-major
    }
    if (m[0][3] != 0 || m[1][3] != 0 || m[2][3] != 0 || m[3][3] != 1)
      fail(at, "the last row must be [0, 0, 0, 1] (affine transforms only)");
    return m;
  }
  // parent_from_node = T R S: scale first, then rotate, then translate.
  Mat4d m(1.0);
  if (node.contains("translate")) m = glm::translate(m, read_vec3(node["translate"], child(where, "translate")));
  if (node.contains("rotate")) {
    const std::string at = child(where, "rotate");
    const json& rotate = require_object(node["rotate"], at);
    check_keys(rotate, at, {"axis", "degrees"});
    if (!rotate.contains("axis") || !rotate.contains("degrees")) fail(at, "rotate needs 'axis' and 'degrees'");
    const Vec3d axis = read_vec3(rotate["axis"], child(at, "axis"));
    if (!(glm::length(axis) > 0)) fail(child(at, "axis"), "rotation axis is zero");
    const double degrees = read_number(rotate["degrees"], child(at, "degrees"));
    m = glm::rotate(m, degrees * std::numbers::pi / 180.0, glm::normalize(axis));
  }
  if (node.contains("scale")) {
    const std::string at = child(where, "scale");
    const Vec3d scale = node["scale"].is_number() ? Vec3d(read_number(node["scale"], at)) : read_vec3(node["scale"], at);
    if (scale.x == 0 || scale.y == 0 || scale.z == 0) fail(at, "scale factors must be non-zero");
    m = glm::scale(m, scale);
  }
  return m;
}

std::uint32_t SceneReader::read_node(const json& value, const std::string& where, Scene& scene, std::size_t depth) {
  if (depth >= kMaxNodeDepth)  // the path is thousands of characters long here: name its start only
    fail(where.substr(0, where.find("/children")) + "/children/...",
         fmt::format("node hierarchy deeper than {} levels", kMaxNodeDepth));
  require_object(value, where);
  check_keys(value, where, {"name", "translate", "rotate", "scale", "matrix", "models", "children"});
  Node node;
  if (value.contains("name")) node.name = read_string(value["name"], child(where, "name"));
  node.parent_from_node = read_transform(value, where);
  if (value.contains("models")) {
    const std::string at = child(where, "models");
    const json& models = require_array(value["models"], at);
    for (std::size_t i = 0; i < models.size(); ++i) {
      const std::string model_at = child(at, i);
      require_object(models[i], model_at);
      check_keys(models[i], model_at, {"geometry", "material"});
      if (!models[i].contains("geometry")) fail(model_at, "missing key 'geometry'");
      if (!models[i].contains("material")) fail(model_at, "missing key 'material'");
      Model model;
      const Model geometry = read_geometry(models[i]["geometry"], child(model_at, "geometry"));
      model.mesh = geometry.mesh;
      model.sphere = geometry.sphere;
      const std::string material = read_string(models[i]["material"], child(model_at, "material"));
      auto it = material_index_.find(material);
      if (it == material_index_.end())
        fail(child(model_at, "material"), fmt::format("no material named '{}' in /materials", material));
      model.material = it->second;
      node.models.push_back(std::move(model));
    }
  }
  // Children are read after this node is stored: their indices follow it (pre-order).
  const auto index = static_cast<std::uint32_t>(scene.nodes.size());
  scene.nodes.push_back(std::move(node));
  if (value.contains("children")) {
    const std::string at = child(where, "children");
    const json& children = require_array(value["children"], at);
    for (std::size_t i = 0; i < children.size(); ++i) {
      const std::uint32_t child_index = read_node(children[i], child(at, i), scene, depth + 1);
      scene.nodes[index].children.push_back(child_index);
    }
  }
  return index;
}

Scene SceneReader::read(const json& document) {
  require_object(document, "");
  check_keys(document, "", {"image", "max_depth", "background", "output", "display", "camera", "materials",
                            "geometries", "lights", "nodes"});
  Scene scene;
  scene.source = path_;
  read_settings(document, scene);
  if (!document.contains("camera")) fail("", "missing key 'camera'");
  scene.camera = read_camera(document["camera"], "/camera");

  if (document.contains("materials")) {
    for (const auto& [name, value] : require_object(document["materials"], "/materials").items()) {
      material_index_[name] = static_cast<std::uint32_t>(scene.materials.size());
      scene.materials.push_back(read_material(value, "/materials/" + name, name));
    }
  }
  if (document.contains("geometries"))
    for (const auto& [name, value] : require_object(document["geometries"], "/geometries").items())
      named_geometry_[name] = read_geometry(value, "/geometries/" + name);
  if (document.contains("lights")) {
    const json& lights = require_array(document["lights"], "/lights");
    for (std::size_t i = 0; i < lights.size(); ++i) scene.lights.push_back(read_light(lights[i], child("/lights", i)));
  }

  scene.nodes.push_back(Node{"<root>", Mat4d(1.0), {}, {}});
  scene.root = 0;
  if (document.contains("nodes")) {
    const json& nodes = require_array(document["nodes"], "/nodes");
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      const std::uint32_t index = read_node(nodes[i], child("/nodes", i), scene, 0);
      scene.nodes[0].children.push_back(index);
    }
  }
  return scene;
}

std::string read_text_file(const std::string& path) {
  std::error_code error;
  if (!fs::is_regular_file(path, error)) throw InputError(path, "", fs::exists(path) ? "not a regular file" : "no such file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "", "cannot open file");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// "line:column" (1-based) of the 1-based byte offset `byte` in `text`.
std::string line_column(const std::string& text, std::size_t byte) {
  std::size_t line = 1, column = 1;
  for (std::size_t i = 0; i + 1 < byte && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++line;
      column = 1;
    } else {
      ++column;
    }
  }
  return fmt::format("{}:{}", line, column);
}

}  // namespace

Scene parse_scene_json(const std::string& text, const std::string& path) {
  if (text.starts_with("\xFF\xFE") || text.starts_with("\xFE\xFF"))
    throw InputError(path, "", "the file is UTF-16; scene files must be UTF-8 (or ASCII)");
  // Said here, as nlohmann's wording for it differs between versions.
  if (text.find_first_not_of(" \t\r\n") == std::string::npos) throw InputError(path, "", "empty file");
  json document;
  try {
    document = json::parse(text, nullptr, /*allow_exceptions=*/true, /*ignore_comments=*/true);
  } catch (const json::parse_error& error) {
    // Report line:column of the byte where parsing stopped; keep only nlohmann's reason text.
    std::string reason = error.what();
    const std::size_t colon = reason.find(": ", reason.find("parse error"));
    if (colon != std::string::npos) reason = reason.substr(colon + 2);
    throw InputError(path, line_column(text, error.byte), "JSON syntax error: " + reason);
  } catch (const json::out_of_range& error) {
    // nlohmann refuses numbers beyond double's range ("number overflow parsing '1e999'") without
    // a position; find the literal in the text to give one.
    std::string reason = error.what();
    const std::size_t open = reason.find('\''), close = reason.rfind('\'');
    const std::string literal = open < close ? reason.substr(open + 1, close - open - 1) : "";
    const std::size_t at = literal.empty() ? std::string::npos : text.find(literal);
    throw InputError(path, at == std::string::npos ? "" : line_column(text, at + 1),
                     fmt::format("number {} is out of range (not a finite double)", literal));
  }
  Scene scene = SceneReader(path).read(document);
  validate_scene(scene);
  return scene;
}

namespace {

std::string lower_extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

}  // namespace

bool is_gltf_path(const std::string& path) {
  const std::string ext = lower_extension(path);
  return ext == ".gltf" || ext == ".glb";
}

std::optional<std::string> declared_output(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext != ".json" && ext != ".test") return std::nullopt;
  std::ifstream file(path, std::ios::binary);
  if (!file || fs::is_directory(path)) return std::nullopt;
  std::ostringstream text;
  text << file.rdbuf();
  if (ext == ".json") {
    const json document = json::parse(text.str(), nullptr, /*allow_exceptions=*/false, /*ignore_comments=*/true);
    if (!document.is_object() || !document.contains("output") || !document["output"].is_string()) return std::nullopt;
    return document["output"].get<std::string>();
  }
  // .test: the last "output FILENAME" line counts, as in the loader.
  std::optional<std::string> output;
  std::istringstream lines(text.str());
  for (std::string line; std::getline(lines, line);) {
    std::istringstream words(line);
    std::string command, name, extra;
    if (words >> command >> name && command == "output" && !(words >> extra)) output = name;
  }
  return output;
}

Scene load_scene(const std::string& path, const GltfOptions& gltf, LoadReport* report) {
  const std::string ext = lower_extension(path);
  if (fs::is_directory(path))
    throw InputError(path, "", "is a directory, not a scene file (name the scene files in it, e.g. DIR/*.gltf)");
  if (ext == ".json") return parse_scene_json(read_text_file(path), path);
  if (ext == ".test") return load_test_scene(path);  // CSE167x ray-tracer scenes, validated
  if (is_gltf_path(path)) return load_gltf_scene(path, gltf, report);  // validated
  if (ext == ".obj") return load_obj_scene(path, report);     // Wavefront OBJ + MTL, validated
  if (!fs::exists(path)) throw InputError(path, "", "no such file");
  throw InputError(path, "",
                   fmt::format("unsupported scene format '{}' (supported: .json, .test, .gltf, .glb, .obj)", ext));
}

}  // namespace rt
