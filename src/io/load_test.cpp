// The CSE167x / CS184.1x ".test" scene format. The semantics (defaults, per-object ambient,
// right-multiplied transforms captured at declaration, world-space lights, ...) follow the
// course's specification as summarised in docs/scene-formats.md.

#include "rt/io/load_test.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <vector>

#include <fmt/format.h>
#include <glm/gtc/matrix_transform.hpp>

#include "rt/core/error.h"
#include "rt/core/memory.h"
#include "rt/scene/shapes.h"

namespace rt {

namespace {

namespace fs = std::filesystem;

// `maxverts` / `maxvertnorms` above this are refused before anything is allocated.
constexpr double kMaxVertexCount = 1e8;

enum class Command {
  size, maxdepth, output, camera, sphere, maxverts, maxvertnorms, vertex, vertexnormal, tri, trinormal,
  translate, rotate, scale, push_transform, pop_transform, directional, point, attenuation,
  ambient, diffuse, specular, shininess, emission,
};

struct CommandSpec {
  Command command;
  std::size_t parameters;
  const char* usage;  // parameter names, for messages
};

const std::map<std::string_view, CommandSpec>& command_table() {
  static const std::map<std::string_view, CommandSpec> table = {
      {"size", {Command::size, 2, "width height"}},
      {"maxdepth", {Command::maxdepth, 1, "depth"}},
      {"output", {Command::output, 1, "filename"}},
      {"camera", {Command::camera, 10, "fromx fromy fromz atx aty atz upx upy upz fovy"}},
      {"sphere", {Command::sphere, 4, "x y z radius"}},
      {"maxverts", {Command::maxverts, 1, "number"}},
      {"maxvertnorms", {Command::maxvertnorms, 1, "number"}},
      {"vertex", {Command::vertex, 3, "x y z"}},
      {"vertexnormal", {Command::vertexnormal, 6, "x y z nx ny nz"}},
      {"tri", {Command::tri, 3, "v1 v2 v3"}},
      {"trinormal", {Command::trinormal, 3, "v1 v2 v3"}},
      {"translate", {Command::translate, 3, "x y z"}},
      {"rotate", {Command::rotate, 4, "x y z angle"}},
      {"scale", {Command::scale, 3, "x y z"}},
      {"pushTransform", {Command::push_transform, 0, ""}},
      {"popTransform", {Command::pop_transform, 0, ""}},
      {"directional", {Command::directional, 6, "x y z r g b"}},
      {"point", {Command::point, 6, "x y z r g b"}},
      {"attenuation", {Command::attenuation, 3, "const linear quadratic"}},
      {"ambient", {Command::ambient, 3, "r g b"}},
      {"diffuse", {Command::diffuse, 3, "r g b"}},
      {"specular", {Command::specular, 3, "r g b"}},
      {"shininess", {Command::shininess, 1, "s"}},
      {"emission", {Command::emission, 3, "r g b"}},
  };
  return table;
}

bool equal_ignoring_case(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(a[i])) != std::tolower(static_cast<unsigned char>(b[i]))) return false;
  return true;
}

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

// The course's material state. The course adds `ambient` once per object, independent of
// lights and shadows, exactly like `emission`; our shader multiplies Material::ambient by each
// unshadowed light instead. So both go into Material::emission and Material::ambient stays 0.
struct MaterialState {
  Color ambient{0.2f};  // course default .2 .2 .2
  Color diffuse{0.0f};
  Color specular{0.0f};
  Color emission{0.0f};
  float shininess = 0.0f;

  Material to_material() const {
    Material m;
    m.ambient = Color(0.0f);
    m.emission = ambient + emission;
    m.diffuse = diffuse;
    m.specular = specular;
    m.shininess = shininess;
    return m;
  }
};

using MaterialKey = std::array<float, 13>;

MaterialKey key_of(const Material& m) {
  return {m.ambient.r,  m.ambient.g,  m.ambient.b,  m.diffuse.r,  m.diffuse.g,  m.diffuse.b, m.specular.r,
          m.specular.g, m.specular.b, m.emission.r, m.emission.g, m.emission.b, m.shininess};
}

class TestSceneParser {
 public:
  explicit TestSceneParser(std::string path) : path_(std::move(path)) {}

  Scene parse(const std::string& text);

 private:
  [[noreturn]] void fail(const std::string& reason) const { throw InputError(path_, std::to_string(line_), reason); }

  void execute(const CommandSpec& spec);

  double number(std::size_t index) const;
  Vec3d vec3(std::size_t first) const { return {number(first), number(first + 1), number(first + 2)}; }
  Color color(std::size_t first) const;
  Vec3f float32(const Vec3d& v) const;  // fails if a component overflows float
  long long integer(std::size_t index, long long min_value, long long max_value, const char* what) const;
  std::size_t vertex_count_limit(std::size_t index) const;

  void add_triangle(const std::array<Vec3f, 3>& positions, const std::array<Vec3f, 3>& normals);
  void add_sphere(const Vec3d& center, double radius);
  std::uint32_t current_material();
  std::uint32_t add_node(const std::string& name);
  void close_open_mesh();

  std::string path_;
  std::size_t line_ = 0;
  std::string_view command_name_;
  std::vector<std::string_view> args_;

  Scene scene_;
  bool have_size_ = false;
  bool have_camera_ = false;
  std::vector<Mat4d> stack_{Mat4d(1.0)};
  MaterialState material_;
  Vec3d attenuation_{1.0, 0.0, 0.0};
  std::optional<std::size_t> max_vertices_, max_vertex_normals_;
  std::vector<Vec3f> vertices_;
  std::vector<std::pair<Vec3f, Vec3f>> vertex_normals_;  // position, unit normal
  std::map<MaterialKey, std::uint32_t> material_index_;

  // Consecutive triangles with the same transform and material share one mesh under one node.
  struct OpenMesh {
    std::uint32_t node;
    Mat4d transform;
    std::uint32_t material;
    TriangleMesh mesh;
  };
  std::optional<OpenMesh> open_;
};

double TestSceneParser::number(std::size_t index) const {
  std::string_view token = args_[index];
  std::string_view digits = token;
  // from_chars takes no leading '+', which the course files use ("vertex +1 -1 0").
  if (digits.size() > 1 && digits[0] == '+' && digits[1] != '-' && digits[1] != '+') digits.remove_prefix(1);
  double value = 0.0;
  const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
  if (error == std::errc::result_out_of_range)
    fail(fmt::format("parameter {} of '{}' is out of range: '{}'", index + 1, command_name_, token));
  if (error != std::errc{} || end != digits.data() + digits.size())
    fail(fmt::format("parameter {} of '{}' is not a number: '{}'", index + 1, command_name_, token));
  if (!std::isfinite(value)) fail(fmt::format("parameter {} of '{}' is not finite: '{}'", index + 1, command_name_, token));
  return value;
}

Color TestSceneParser::color(std::size_t first) const {
  const Vec3d rgb = vec3(first);
  if (rgb.r < 0.0 || rgb.g < 0.0 || rgb.b < 0.0)
    fail(fmt::format("colour components of '{}' must be >= 0", command_name_));
  return Color(float32(rgb));
}

Vec3f TestSceneParser::float32(const Vec3d& v) const {
  const Vec3f f(v);
  if (!std::isfinite(f.x) || !std::isfinite(f.y) || !std::isfinite(f.z))
    fail(fmt::format("a parameter of '{}' is beyond the range of float32", command_name_));
  return f;
}

long long TestSceneParser::integer(std::size_t index, long long min_value, long long max_value, const char* what) const {
  const double value = number(index);
  if (value != std::floor(value)) fail(fmt::format("{} must be an integer, got '{}'", what, args_[index]));
  if (value < static_cast<double>(min_value) || value > static_cast<double>(max_value))
    fail(fmt::format("{} {} is outside {}..{}", what, args_[index], min_value, max_value));
  return static_cast<long long>(value);
}

std::size_t TestSceneParser::vertex_count_limit(std::size_t index) const {
  const double value = number(index);
  if (value != std::floor(value) || value < 0.0)
    fail(fmt::format("'{}' needs a non-negative integer, got '{}'", command_name_, args_[index]));
  if (value > kMaxVertexCount)
    fail(fmt::format("'{}' {} exceeds the limit of {:.0f} (that many vertices would need {})", command_name_,
                     args_[index], kMaxVertexCount, format_bytes(static_cast<std::uint64_t>(std::min(value, 1e17)) * 24)));
  return static_cast<std::size_t>(value);
}

std::uint32_t TestSceneParser::current_material() {
  const Material material = material_.to_material();
  const auto [it, inserted] = material_index_.try_emplace(key_of(material), static_cast<std::uint32_t>(scene_.materials.size()));
  if (inserted) {
    scene_.materials.push_back(material);
    scene_.materials.back().name = fmt::format("line {}", line_);
  }
  return it->second;
}

std::uint32_t TestSceneParser::add_node(const std::string& name) {
  Node node;
  node.name = name;
  node.parent_from_node = stack_.back();
  const auto index = static_cast<std::uint32_t>(scene_.nodes.size());
  scene_.nodes.push_back(std::move(node));
  scene_.nodes[scene_.root].children.push_back(index);
  return index;
}

void TestSceneParser::close_open_mesh() {
  if (!open_) return;
  scene_.nodes[open_->node].models.push_back(
      Model{std::make_shared<const TriangleMesh>(std::move(open_->mesh)), open_->material});
  open_.reset();
}

void TestSceneParser::add_triangle(const std::array<Vec3f, 3>& positions, const std::array<Vec3f, 3>& normals) {
  const std::uint32_t material = current_material();
  if (!open_ || open_->material != material || open_->transform != stack_.back()) {
    close_open_mesh();
    open_ = OpenMesh{add_node(fmt::format("tri (line {})", line_)), stack_.back(), material, {}};
  }
  TriangleMesh& mesh = open_->mesh;
  const auto base = static_cast<unsigned>(mesh.positions.size());
  for (int k = 0; k < 3; ++k) {
    mesh.positions.push_back(positions[k]);
    mesh.normals.push_back(normals[k]);
  }
  mesh.triangles.push_back({base, base + 1, base + 2});
}

void TestSceneParser::add_sphere(const Vec3d& center, double radius) {
  close_open_mesh();
  const std::uint32_t material = current_material();
  // An exact sphere in the node's object space; the node carries the current transform, so
  // non-uniform scales make ellipsoids.
  const std::uint32_t node = add_node(fmt::format("sphere (line {})", line_));
  scene_.nodes[node].models.push_back(Model{nullptr, material, Sphere{center, radius}});
}

void TestSceneParser::execute(const CommandSpec& spec) {
  switch (spec.command) {
    case Command::size: {
      if (have_size_) fail("'size' given twice (it must be the first command, once)");
      scene_.settings.width = static_cast<int>(integer(0, 1, kMaxImageSide, "image width"));
      scene_.settings.height = static_cast<int>(integer(1, 1, kMaxImageSide, "image height"));
      have_size_ = true;
      break;
    }
    case Command::maxdepth:
      scene_.settings.max_depth = static_cast<int>(integer(0, 0, kMaxReflectionDepth, "maxdepth"));
      break;
    case Command::output:
      scene_.settings.output = std::string(args_[0]);
      break;
    case Command::camera: {
      Camera camera;
      camera.eye = vec3(0);
      camera.target = vec3(3);
      camera.up = vec3(6);
      camera.fovy_degrees = number(9);
      if (auto problem = find_camera_problem(camera)) fail("camera: " + problem->reason);
      scene_.camera = camera;
      have_camera_ = true;
      break;
    }
    case Command::sphere: {
      const Vec3d center = vec3(0);
      const double radius = number(3);
      if (!(radius > 0.0)) fail(fmt::format("sphere radius must be > 0, got {}", args_[3]));
      add_sphere(center, radius);
      break;
    }
    case Command::maxverts:
    case Command::maxvertnorms: {
      auto& limit = spec.command == Command::maxverts ? max_vertices_ : max_vertex_normals_;
      if (limit) fail(fmt::format("'{}' given twice", command_name_));
      limit = vertex_count_limit(0);
      if (spec.command == Command::maxverts) {
        vertices_.reserve(std::min<std::size_t>(*limit, 1u << 20));
      } else {
        vertex_normals_.reserve(std::min<std::size_t>(*limit, 1u << 20));
      }
      break;
    }
    case Command::vertex: {
      if (!max_vertices_) fail("'vertex' before 'maxverts'");
      if (vertices_.size() >= *max_vertices_) fail(fmt::format("more vertices than maxverts {}", *max_vertices_));
      vertices_.push_back(float32(vec3(0)));
      break;
    }
    case Command::vertexnormal: {
      if (!max_vertex_normals_) fail("'vertexnormal' before 'maxvertnorms'");
      if (vertex_normals_.size() >= *max_vertex_normals_)
        fail(fmt::format("more vertex normals than maxvertnorms {}", *max_vertex_normals_));
      const Vec3d normal = vec3(3);
      if (!(glm::length(normal) > 0.0)) fail("vertexnormal: the normal is zero");
      vertex_normals_.emplace_back(float32(vec3(0)), Vec3f(glm::normalize(normal)));
      break;
    }
    case Command::tri:
    case Command::trinormal: {
      const bool with_normals = spec.command == Command::trinormal;
      const auto& limit = with_normals ? max_vertex_normals_ : max_vertices_;
      const char* limit_name = with_normals ? "maxvertnorms" : "maxverts";
      const std::size_t defined = with_normals ? vertex_normals_.size() : vertices_.size();
      if (!limit) fail(fmt::format("'{}' before '{}'", command_name_, limit_name));
      std::array<std::size_t, 3> index{};
      for (std::size_t k = 0; k < 3; ++k) {
        const double value = number(k);
        if (value != std::floor(value) || value < 0.0)
          fail(fmt::format("vertex index '{}' is not a non-negative integer", args_[k]));
        if (value >= static_cast<double>(*limit))
          fail(fmt::format("vertex index {} is beyond {} {}", args_[k], limit_name, *limit));
        if (value >= static_cast<double>(defined))
          fail(fmt::format("vertex index {} is out of range: {} {} defined so far", args_[k], defined,
                           with_normals ? "vertex normals" : "vertices"));
        index[k] = static_cast<std::size_t>(value);
      }
      std::array<Vec3f, 3> positions, normals;
      if (with_normals) {
        for (int k = 0; k < 3; ++k) {
          positions[k] = vertex_normals_[index[k]].first;
          normals[k] = vertex_normals_[index[k]].second;
        }
      } else {
        for (int k = 0; k < 3; ++k) positions[k] = vertices_[index[k]];
        // Flat shading with the face normal (v2 - v1) x (v3 - v1). A zero-area triangle has none;
        // flatten_scene drops it anyway, so any unit vector does.
        const Vec3d face = glm::cross(Vec3d(positions[1]) - Vec3d(positions[0]), Vec3d(positions[2]) - Vec3d(positions[0]));
        const double length = glm::length(face);
        const Vec3f normal = length > 0.0 ? Vec3f(face / length) : Vec3f(0.0f, 0.0f, 1.0f);
        normals = {normal, normal, normal};
      }
      add_triangle(positions, normals);
      break;
    }
    case Command::translate:
      stack_.back() = glm::translate(stack_.back(), vec3(0));
      break;
    case Command::rotate: {
      const Vec3d axis = vec3(0);
      if (!(glm::length(axis) > 0.0)) fail("rotation axis is zero");
      stack_.back() = glm::rotate(stack_.back(), number(3) * std::numbers::pi / 180.0, glm::normalize(axis));
      break;
    }
    case Command::scale: {
      const Vec3d factors = vec3(0);
      if (factors.x == 0.0 || factors.y == 0.0 || factors.z == 0.0) fail("scale factors must be non-zero");
      stack_.back() = glm::scale(stack_.back(), factors);
      break;
    }
    case Command::push_transform:
      stack_.push_back(stack_.back());
      break;
    case Command::pop_transform:
      if (stack_.size() == 1) fail("'popTransform' without a matching 'pushTransform' (the stack is empty)");
      stack_.pop_back();
      break;
    case Command::directional: {
      // Lights are world space: the transform stack does not apply to them (see the docs).
      const Vec3d direction = vec3(0);
      if (direction == Vec3d(0.0)) fail("directional light has a zero direction");
      Light light;
      light.position = Vec4d(direction, 0.0);
      light.color = color(3);
      light.attenuation = Vec3d(1.0, 0.0, 0.0);  // directional lights are never attenuated
      scene_.lights.push_back(light);
      break;
    }
    case Command::point: {
      Light light;
      light.position = Vec4d(vec3(0), 1.0);
      light.color = color(3);
      light.attenuation = attenuation_;
      scene_.lights.push_back(light);
      break;
    }
    case Command::attenuation: {
      const Vec3d coefficients = vec3(0);
      if (coefficients.x < 0.0 || coefficients.y < 0.0 || coefficients.z < 0.0 || coefficients == Vec3d(0.0))
        fail("attenuation coefficients must be >= 0 and not all zero");
      attenuation_ = coefficients;
      break;
    }
    case Command::ambient:
      material_.ambient = color(0);
      break;
    case Command::diffuse:
      material_.diffuse = color(0);
      break;
    case Command::specular:
      material_.specular = color(0);
      break;
    case Command::emission:
      material_.emission = color(0);
      break;
    case Command::shininess: {
      const double shininess = number(0);
      if (shininess < 0.0) fail(fmt::format("shininess must be >= 0, got {}", args_[0]));
      material_.shininess = static_cast<float>(shininess);
      break;
    }
  }
}

Scene TestSceneParser::parse(const std::string& text) {
  scene_.source = path_;
  scene_.settings = RenderSettings{};  // max_depth 5, black background, no output name
  scene_.nodes.push_back(Node{"<root>", Mat4d(1.0), {}, {}});
  scene_.root = 0;

  const auto& table = command_table();
  std::size_t begin = text.starts_with("\xEF\xBB\xBF") ? 3 : 0;  // a UTF-8 byte order mark is not a command
  line_ = 0;
  while (begin < text.size()) {
    std::size_t end = text.find('\n', begin);
    if (end == std::string::npos) end = text.size();
    const std::string_view line(text.data() + begin, end - begin);
    begin = end + 1;
    ++line_;
    for (unsigned char c : line)
      if (c < 0x20 && !is_space(char(c)))
        fail(fmt::format("binary data (byte 0x{:02x}): not a text file", static_cast<unsigned>(c)));

    args_.clear();
    for (std::size_t i = 0; i < line.size();) {
      while (i < line.size() && is_space(line[i])) ++i;
      const std::size_t start = i;
      while (i < line.size() && !is_space(line[i])) ++i;
      if (i > start) args_.push_back(line.substr(start, i - start));
    }
    if (args_.empty() || args_[0].starts_with('#')) continue;
    command_name_ = args_[0];
    args_.erase(args_.begin());

    const auto it = table.find(command_name_);
    if (it == table.end()) {
      for (const auto& [name, spec] : table)
        if (equal_ignoring_case(name, command_name_))
          fail(fmt::format("unknown command '{}' (did you mean '{}'? commands are case-sensitive)", command_name_, name));
      fail(fmt::format("unknown command '{}'", command_name_));
    }
    const CommandSpec& spec = it->second;
    for (std::string_view arg : args_)
      if (arg.starts_with('#')) fail("a comment must be on a line of its own (the line must start with '#')");
    if (!have_size_ && spec.command != Command::size)
      fail(fmt::format("'size' must be the first command, found '{}'", command_name_));
    if (args_.size() != spec.parameters) {
      if (spec.parameters == 0)
        fail(fmt::format("'{}' takes no parameters, got {}", command_name_, args_.size()));
      fail(fmt::format("'{}' takes {} parameter(s) ({}), got {}", command_name_, spec.parameters, spec.usage,
                       args_.size()));
    }
    execute(spec);
  }
  close_open_mesh();

  // Problems of the file as a whole are reported at its last line.
  line_ = std::max<std::size_t>(line_, 1);
  if (!have_size_) fail("no 'size' command (it must be the first command)");
  if (!have_camera_) fail("no 'camera' command");
  validate_scene(scene_);
  return std::move(scene_);
}

std::string read_text_file(const std::string& path) {
  std::error_code error;
  if (!fs::is_regular_file(path, error))
    throw InputError(path, "", fs::exists(path, error) ? "not a regular file" : "no such file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "", "cannot open file");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw InputError(path, "", "cannot read file");
  return text.str();
}

}  // namespace

Scene parse_test_scene(const std::string& text, const std::string& path) {
  return TestSceneParser(path).parse(text);
}

Scene load_test_scene(const std::string& path) {
  return parse_test_scene(read_text_file(path), path);
}

}  // namespace rt
