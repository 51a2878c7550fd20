#pragma once
// The hierarchical scene graph, mirroring the seed's RTScene: nodes with a local transform,
// child nodes and models (geometry + material), plus lights, a camera and render settings.
// Loaders build it; flatten_scene() turns it into world-space triangle buffers.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rt/core/display.h"
#include "rt/core/math.h"

namespace rt {

// How texture coordinates outside [0, 1] map into the image (glTF sampler wrap modes).
enum class TextureWrap { repeat, clamp_to_edge, mirrored_repeat };

// Texture coordinates at a point of a surface, both sets (texture space, float32).
struct TexCoords {
  Vec2f uv0{0.0f};  // TriangleMesh::texcoords
  Vec2f uv1{0.0f};  // TriangleMesh::texcoords1
};

// glTF's KHR_texture_transform: uv' = offset + R(rotation) (scale * uv), R turning
// counter-clockwise by `rotation` radians (the extension's GLSL, column-major).
struct TextureTransform {
  Vec2f offset{0.0f};
  float rotation = 0.0f;
  Vec2f scale{1.0f};

  bool identity() const { return offset == Vec2f(0.0f) && rotation == 0.0f && scale == Vec2f(1.0f); }
  Vec2f apply(Vec2f uv) const {
    const float c = std::cos(rotation), s = std::sin(rotation);
    const Vec2f scaled = scale * uv;
    return offset + Vec2f(c * scaled.x - s * scaled.y, s * scaled.x + c * scaled.y);
  }
};

// An image looked up by a mesh's texcoords, (0, 0) at the top-left corner of the image (the glTF
// convention). `path` names an image file; when `encoded` is set, the encoded file itself (PNG,
// JPEG, ...) was embedded in the scene file and `path` only labels it in messages.
// Colour textures hold sRGB-encoded values, decoded to linear RGB when sampled; data textures
// (normal, metallic-roughness, occlusion maps) are read as stored.
struct Texture {
  std::string path;  // empty: no texture
  std::shared_ptr<const std::string> encoded;
  TextureWrap wrap_s = TextureWrap::repeat;  // along u (image columns)
  TextureWrap wrap_t = TextureWrap::repeat;  // along v (image rows)
  int texcoord = 0;  // the coordinate set: 0 or 1 (TexCoords::uv0, uv1)
  TextureTransform transform;

  bool empty() const { return path.empty(); }
  // The coordinates this texture is looked up at, at a point with coordinates `uv`.
  Vec2f lookup_uv(const TexCoords& uv) const {
    const Vec2f& chosen = texcoord == 1 ? uv.uv1 : uv.uv0;
    return transform.identity() ? chosen : transform.apply(chosen);
  }
};

// How a material's alpha (coverage) is used (glTF alphaMode; docs/alpha.md).
enum class AlphaMode {
  opaque,  // alpha ignored
  mask,    // the surface exists where alpha >= alpha_cutoff; rays of every kind pass elsewhere
  blend,   // seen with weight alpha, the rest of the ray going on straight (no bending)
};

// How a surface is seen from behind: from the side its geometric normal (p1 - p0) x (p2 - p0)
// points away from (docs/scene-formats.md, "Front and back faces").
enum class BackFace {
  unflipped,  // shaded with its own normals, which face away (the course's: .test, native default)
  flipped,    // shaded with the normals turned towards the viewer (glTF doubleSided, OBJ)
  culled,     // not there: rays of every kind pass it (glTF single-sided); triangles only
};

// glTF metallic-roughness inputs of a material whose Phong terms vary over the surface (a
// metallic-roughness texture, or a textured or vertex-coloured metal): the shader maps them per
// hit with phong_from_metallic_roughness (rt/scene/metallic_roughness.h), where a constant
// material is mapped once by the loader.
struct MetallicRoughness {
  Color base_color{1.0f};       // baseColorFactor, linear RGB; the diffuse texture and vertex colours multiply it
  float metallic = 1.0f;        // metallicFactor, x the texture's blue channel
  float roughness = 1.0f;       // roughnessFactor, x the texture's green channel
  float dielectric_f0 = 0.04f;  // reflectance at normal incidence of the non-metal, ((ior - 1) / (ior + 1))^2
  Texture texture;              // metallicRoughnessTexture (linear); may be empty
};

// Phong / Blinn-Phong material of the seed's FindColor. Colours are linear RGB in [0, inf).
struct Material {
  std::string name;
  Color ambient{0.0f};
  Color diffuse{0.0f};
  Color specular{0.0f};   // also weights the recursive mirror reflection unless `reflective` is set
  Color emission{0.0f};
  float shininess = 1.0f;  // Blinn-Phong exponent sigma, >= 0
  // Weight of the recursive mirror reflection when it differs from `specular` (OBJ/MTL: only
  // illum 3 to 7 reflect; glTF: only smooth surfaces). Unset: `specular`, as in the seed. Set and
  // zero: no reflection ray.
  std::optional<Color> reflective;
  Texture diffuse_texture;  // multiplies `diffuse` and `ambient` at each hit

  // Maps sampled per hit besides the diffuse texture (rt/render/surface_maps.h).
  std::optional<MetallicRoughness> metallic_roughness;  // set: diffuse, specular, shininess and reflective come from it
  Texture normal_texture;     // tangent space (+X along u, +Y up the image, glTF's convention); needs tangents
  float normal_scale = 1.0f;  // multiplies the map's X and Y (glTF normalTexture.scale)
  Texture occlusion_texture;  // red channel r: `ambient` x (1 + occlusion_strength (r - 1))
  float occlusion_strength = 1.0f;
  Texture specular_texture;   // colour multiplying `specular` (MTL map_Ks)
  Texture shininess_texture;  // first channel multiplying `shininess` (MTL map_Ns)
  Texture bump_texture;       // height map, first channel (MTL bump, map_bump), in units of bump_scale
  float bump_scale = 1.0f;    // MTL -bm
  // Whether the shader needs the per-hit maps stage for this material (vertex colours aside).
  bool has_surface_maps() const {
    return metallic_roughness || !normal_texture.empty() || !occlusion_texture.empty() || !specular_texture.empty() ||
           !shininess_texture.empty() || !bump_texture.empty();
  }
  // An emitter (OBJ/MTL Ke, glTF emissive, native "emitter": true): `emission` times
  // `emission_texture` is radiance (linear RGB) leaving the front side of each triangle (counter-
  // clockwise seen from the front); rays see it from that side only, and it lights the scene as an
  // area light (rt/render/area_lights.h). Otherwise `emission` is the seed's self-emission: added
  // at every hit from either side, lighting nothing (CSE167x .test, native scenes by default).
  bool emits_light = false;
  Texture emission_texture;  // multiplies `emission` of an emitter at each point it is evaluated

  // A smooth dielectric (glass, water) where `transmission` is not black (OBJ/MTL illum 4/6/7,
  // glTF KHR_materials_transmission, native "transmission"; rt/render/dielectric.h, docs/glass.md).
  // Its mirror reflection is then weighted by the Fresnel reflectance F of the interface instead of
  // `reflective`/`specular`, and a refracted ray carries (1 - F) * transmission. The Phong terms of
  // the lights (ambient, diffuse, highlight) are added as for any material.
  Color transmission{0.0f};
  // glTF's mix (KHR_materials_transmission): at each point a share c = transmission_factor x the
  // red channel of transmission_texture is glass, tinted by the base colour (`transmission` x the
  // diffuse texture), the rest the opaque material: diffuse and ambient are weighted by 1 - c, the
  // mirror reflection is (1 - c) reflective + c F. Off (native and MTL glass): c = 1 everywhere.
  bool transmission_mix = false;
  float transmission_factor = 1.0f;
  Texture transmission_texture;  // linear (not sRGB); read only when transmission_mix
  float ior = 1.5f;  // index of refraction of the inside (the side the normals point away from); outside is 1
  // Thin-walled (glTF transmission without KHR_materials_volume): a sheet with nothing inside, so
  // the transmitted ray goes on undeflected.
  bool thin_walled = false;
  // Beer–Lambert absorption of light travelling inside (KHR_materials_volume): after
  // attenuation_distance scene units its colour is multiplied by attenuation_color. Infinite: none.
  Color attenuation_color{1.0f};
  float attenuation_distance = std::numeric_limits<float>::infinity();

  // Alpha (glTF alphaMode with baseColorFactor's alpha and the base colour texture's alpha
  // channel; OBJ/MTL d, Tr, map_d; native "alpha"): alpha = `alpha` x alpha_texture's alpha at the
  // texel the hit falls in (no filtering, so cut-outs follow texel edges). An image without an
  // alpha channel gives 1, or with alpha_from_grey its first channel (MTL map_d is a scalar map).
  AlphaMode alpha_mode = AlphaMode::opaque;
  float alpha = 1.0f;
  float alpha_cutoff = 0.5f;  // mask only
  Texture alpha_texture;
  bool alpha_from_grey = false;

  // How back faces are seen. Dielectrics ignore it: their two sides are the two sides of an
  // interface (docs/glass.md).
  BackFace back_face = BackFace::unflipped;
  // Whether hits on triangles of this material are culled from behind.
  bool culls_back_faces() const { return back_face == BackFace::culled && !is_dielectric(); }

  // Whether hits need an alpha test: a mask or blend mode with an alpha below 1 somewhere.
  bool has_alpha() const { return alpha_mode != AlphaMode::opaque && (alpha < 1.0f || !alpha_texture.empty()); }

  // An area light: emits_light with a non-black emission (a black one lights nothing).
  bool is_emitter() const { return emits_light && emission != Color(0.0f); }
  bool is_dielectric() const { return transmission != Color(0.0f); }
};

// A light in world space. position.w == 0: directional, (x, y, z) is the direction towards the
// light (need not be unit length). position.w == 1: point light at (x, y, z).
// Point lights are attenuated by 1 / (c0 + c1 d + c2 d^2), d the world-space distance in scene units;
// directional lights never are. A point light with spot_cos_outer > -1 is a spot light: it is further
// scaled by the square of clamp((cos a - spot_cos_outer) / max(spot_cos_inner - spot_cos_outer, 1e-3), 0, 1),
// a the angle between spot_direction and the direction from the light to the lit point (the glTF
// KHR_lights_punctual falloff).
struct Light {
  Vec4d position{0.0, 0.0, 1.0, 0.0};
  Color color{1.0f};
  Vec3d attenuation{1.0, 0.0, 0.0};  // (constant, linear, quadratic)
  Vec3d spot_direction{0.0, 0.0, -1.0};  // world space, unit: where the spot points
  double spot_cos_inner = -1.0;          // cosines of the cone half-angles, inner >= outer
  double spot_cos_outer = -1.0;

  bool is_directional() const { return position.w == 0.0; }
  bool is_spot() const { return !is_directional() && spot_cos_outer > -1.0; }
};

// Pinhole camera in world space. fovy_degrees is the full vertical field of view, in (0, 180);
// the horizontal extent follows from the image aspect ratio width / height.
struct Camera {
  Vec3d eye{0.0, 0.0, 5.0};
  Vec3d target{0.0, 0.0, 0.0};
  Vec3d up{0.0, 1.0, 0.0};
  double fovy_degrees = 45.0;
};

// An indexed triangle mesh in object space (float32, what the renderer finally stores).
// normals is empty or has one unit vector per position; texcoords is empty or has one (u, v) per
// position (texture space, see Texture); triangles are counter-clockwise
// when seen from the side the geometric normal (p1 - p0) x (p2 - p0) points to.
// The optional attributes, each empty or one per position: texcoords1 a second coordinate set
// (glTF TEXCOORD_1, see Texture::texcoord); colors linear RGBA multiplying the base colour (glTF
// COLOR_0); tangents the tangent frames of normal maps (xyz unit, along increasing u, w = +-1 the
// handedness; see generate_tangents in rt/scene/tangents.h).
struct TriangleMesh {
  std::vector<Vec3f> positions;
  std::vector<Vec3f> normals;
  std::vector<Vec2f> texcoords;
  std::vector<Vec3u> triangles;
  std::vector<Vec2f> texcoords1;
  std::vector<Vec4f> colors;
  std::vector<Vec4f> tangents;
};

// An exact sphere in object space. Under a node's transform it becomes an ellipsoid in general;
// it is intersected as a quadric, not tessellated (unless flattening is asked to tessellate).
struct Sphere {
  Vec3d center{0.0};
  double radius = 1.0;  // > 0, object-space units
};

// A model is a piece of geometry, a triangle mesh or a sphere (exactly one of the two), drawn
// with one material (index into Scene::materials). Meshes are shared so that one loaded mesh can
// be instanced by many models.
struct Model {
  std::shared_ptr<const TriangleMesh> mesh;
  std::uint32_t material = 0;
  std::optional<Sphere> sphere = std::nullopt;
};

// A graph node. parent_from_node maps this node's space to its parent's (double precision).
// children index Scene::nodes; the graph must be acyclic (flatten_scene checks).
struct Node {
  std::string name;
  Mat4d parent_from_node{1.0};
  std::vector<std::uint32_t> children;
  std::vector<Model> models;
};

// Upper limits validate_scene enforces: image sides (keeps pixel counts within 32-bit tile
// arithmetic) and reflection depth (find_color recurses once per level on the thread's stack).
inline constexpr int kMaxImageSide = 1 << 16;
inline constexpr int kMaxReflectionDepth = 1000;

// Largest magnitude of a world-space coordinate (scene units): Embree rejects rays whose origin
// lies beyond +-1.844e18 (FLT_LARGE, an assertion in Debian's build), so the camera eye must stay
// within kMaxEyeCoordinate and geometry (flatten_scene checks every vertex and sphere bound)
// within kMaxWorldCoordinate, which leaves room for an eye framing that geometry from outside.
inline constexpr double kMaxWorldCoordinate = 1e17;
inline constexpr double kMaxEyeCoordinate = 1e18;

// The largest |component| of a world-space point, compared with the limits above.
inline double max_abs_coordinate(const Vec3d& p) { return std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}); }

// Image and integrator settings carried by a scene file; CLI flags may override them.
struct RenderSettings {
  int width = 640;
  int height = 480;
  int max_depth = 5;        // 0 = primary hit only; reflections recurse while depth < max_depth
  Color background{0.0f};   // radiance of rays that miss everything
  std::string output;       // default output file name; empty means "<scene stem>.png"
  // How 8-bit outputs encode the linear image: sRGB for glTF and OBJ, the course's linear
  // floor(255 c) for .test, the native format's "display" key (linear by default).
  DisplayTransform display;
};

struct Scene {
  std::vector<Node> nodes;  // nodes[root] is the root
  std::uint32_t root = 0;
  std::vector<Material> materials;
  std::vector<Light> lights;
  Camera camera;
  RenderSettings settings;
  std::string source;       // file the scene came from, for messages ("<built-in>" for the default)
  std::vector<std::string> notices;  // what the loader skipped or substituted; loading went on
};

// Checks invariants that loaders and hand-built scenes must satisfy (indices in range, finite
// values, sensible sizes, a valid camera). Throws InputError naming scene.source and the offence.
void validate_scene(const Scene& scene);

// What is wrong with a camera: the offending field ("eye", "target", "up" or "fovy") and why.
struct CameraProblem {
  std::string field;
  std::string reason;
};

// The first problem that makes the camera unusable (non-finite values, eye == target, up zero or
// parallel to the view direction, fovy outside (0, 180) degrees), or nullopt if there is none.
std::optional<CameraProblem> find_camera_problem(const Camera& camera);

// Throws InputError naming `source`, "camera.<field>" and the reason if find_camera_problem finds one.
void validate_camera(const Camera& camera, const std::string& source);

// True when some node's triangle mesh uses a material whose uniform emission lights the scene
// (Material::emits_light, non-black emission, no emission texture): loaders then add no headlight,
// the scene's own lamps light it. Emission modulated by a texture (a glow map, as on glTF's
// DamagedHelmet and WaterBottle: mostly dark, with bright details) still lights the scene but does
// not replace the headlight, which would otherwise leave such models black.
bool lit_by_own_emitters(const Scene& scene);

// Sum of weight(node) over every instance of every node reachable from scene.root, a shared
// subgraph counted once per path that reaches it (as flattening expands it), saturating at
// UINT64_MAX. Sizes what flattening will allocate before it does: a file can instance a subtree
// 2^40 times in a few hundred bytes. Iterative, memoised per node; throws InputError naming
// scene.source and a node of the cycle when the hierarchy has one.
std::uint64_t sum_over_instances(const Scene& scene, const std::function<std::uint64_t(const Node&)>& weight);

}  // namespace rt
