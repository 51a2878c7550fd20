// rt's own PNG and JPEG decoding and bilinear lookups (rt/io/decode_image.h, TextureSampler),
// checked against OpenImageIO, the decoder and TextureSystem they replace for these formats.

#include <csetjmp>
#include <cstdio>
#include <filesystem>
#include <random>
#include <set>

#include "catch.h"
#include <jpeglib.h>
#include <nlohmann/json.hpp>
#include <png.h>

#include "rt/io/decode_image.h"
#include "rt/io/image_io.h"
#include "rt/render/texture.h"
#include "test_util.h"

namespace fs = std::filesystem;
using rt_test::TempDir;

namespace {

// A PNG of `width` x `height` with `color_type` and `depth`, sample s of texel i being
// pattern(i, s) (truncated to the depth); `palette`: PLTE entries with tRNS alphas. Written with
// libpng's write API, independent of the decoder under test.
struct PngSpec {
  int width = 7, height = 5, color_type = PNG_COLOR_TYPE_RGB, depth = 8;
  bool interlaced = false;
};

int png_channels(int color_type) {
  switch (color_type) {
    case PNG_COLOR_TYPE_GRAY: return 1;
    case PNG_COLOR_TYPE_GRAY_ALPHA: return 2;
    case PNG_COLOR_TYPE_RGB: return 3;
    case PNG_COLOR_TYPE_RGB_ALPHA: return 4;
    default: return 1;  // palette indices
  }
}

// Sample value of channel c of texel i, in [0, 2^depth).
unsigned pattern(int i, int c, int depth) { return unsigned(i * 37 + c * 101 + 13) % (1u << depth); }

bool write_png_rows(png_structp png, png_infop info, const PngSpec& spec, png_bytepp rows, std::FILE* file) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_init_io(png, file);
  png_set_IHDR(png, info, png_uint_32(spec.width), png_uint_32(spec.height), spec.depth, spec.color_type,
               spec.interlaced ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  if (spec.color_type == PNG_COLOR_TYPE_PALETTE) {
    png_color palette[16];
    png_byte alphas[16];
    for (int k = 0; k < 16; ++k) {
      palette[k] = {png_byte(k * 16), png_byte(255 - k * 8), png_byte(k * 5)};
      alphas[k] = png_byte(k * 17);
    }
    png_set_PLTE(png, info, palette, 16);
    png_set_tRNS(png, info, alphas, 16, nullptr);
  }
  png_write_info(png, info);
  if (spec.depth == 16) png_set_swap(png);
  png_write_image(png, rows);
  png_write_end(png, nullptr);
  return true;
}

void write_test_png(const fs::path& path, const PngSpec& spec) {
  const int channels = png_channels(spec.color_type);
  const int bytes = spec.depth == 16 ? 2 : 1;
  const std::size_t row_bytes = std::size_t((spec.width * channels * spec.depth + 7) / 8);
  std::vector<std::vector<png_byte>> data(std::size_t(spec.height), std::vector<png_byte>(row_bytes * std::size_t(bytes), 0));
  for (int y = 0; y < spec.height; ++y)
    for (int x = 0; x < spec.width; ++x)
      for (int c = 0; c < channels; ++c) {
        const int i = y * spec.width + x;
        const unsigned v = pattern(i, c, spec.color_type == PNG_COLOR_TYPE_PALETTE ? 4 : spec.depth);
        auto& row = data[std::size_t(y)];
        if (spec.depth == 16) {
          const std::size_t at = std::size_t(x * channels + c) * 2;
          row[at] = png_byte(v & 0xff);  // little-endian here, swapped by png_set_swap on write
          row[at + 1] = png_byte(v >> 8);
        } else if (spec.depth == 8) {
          row[std::size_t(x * channels + c)] = png_byte(v);
        } else {  // packed: 1, 2 or 4 bits, grey or palette (one channel)
          const int bit = x * spec.depth;
          row[std::size_t(bit / 8)] |= png_byte(v << (8 - spec.depth - bit % 8));
        }
      }
  std::vector<png_bytep> rows;
  for (auto& row : data) rows.push_back(row.data());
  std::FILE* file = std::fopen(path.c_str(), "wb");
  REQUIRE(file);
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  const bool written = write_png_rows(png, info, spec, rows.data(), file);
  png_destroy_write_struct(&png, &info);
  std::fclose(file);
  REQUIRE(written);
}

struct JpegSpec {
  int width = 33, height = 21, components = 3;
  bool progressive = false;
  int h_sampling = 2, v_sampling = 2;  // of the luma component: 4:2:0 by default
};

bool write_jpeg_rows(jpeg_compress_struct& cinfo, std::jmp_buf& jump, const JpegSpec& spec, std::vector<JSAMPLE>& texels,
                     std::FILE* file) {
  if (setjmp(jump)) return false;
  jpeg_stdio_dest(&cinfo, file);
  cinfo.image_width = JDIMENSION(spec.width);
  cinfo.image_height = JDIMENSION(spec.height);
  cinfo.input_components = spec.components;
  cinfo.in_color_space = spec.components == 1 ? JCS_GRAYSCALE : JCS_RGB;
  jpeg_set_defaults(&cinfo);
  jpeg_set_quality(&cinfo, 85, TRUE);
  if (spec.components == 3) {
    cinfo.comp_info[0].h_samp_factor = spec.h_sampling;
    cinfo.comp_info[0].v_samp_factor = spec.v_sampling;
  }
  if (spec.progressive) jpeg_simple_progression(&cinfo);
  jpeg_start_compress(&cinfo, TRUE);
  while (cinfo.next_scanline < cinfo.image_height) {
    JSAMPROW row = texels.data() + std::size_t(cinfo.next_scanline) * std::size_t(spec.width * spec.components);
    jpeg_write_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_compress(&cinfo);
  return true;
}

struct JpegJump {
  jpeg_error_mgr manager;
  std::jmp_buf jump;
};

[[noreturn]] void on_jpeg_write_error(j_common_ptr cinfo) { std::longjmp(reinterpret_cast<JpegJump*>(cinfo->err)->jump, 1); }

void write_test_jpeg(const fs::path& path, const JpegSpec& spec) {
  std::vector<JSAMPLE> texels(std::size_t(spec.width * spec.height * spec.components));
  for (int y = 0; y < spec.height; ++y)
    for (int x = 0; x < spec.width; ++x)
      for (int c = 0; c < spec.components; ++c)  // smooth ramps with some detail, as photographs have
        texels[std::size_t((y * spec.width + x) * spec.components + c)] =
            JSAMPLE((x * 7 + y * 3 + c * 60 + ((x * y) % 11) * 4) % 256);
  std::FILE* file = std::fopen(path.c_str(), "wb");
  REQUIRE(file);
  jpeg_compress_struct cinfo{};
  JpegJump errors{};
  cinfo.err = jpeg_std_error(&errors.manager);
  errors.manager.error_exit = on_jpeg_write_error;
  jpeg_create_compress(&cinfo);
  const bool written = write_jpeg_rows(cinfo, errors.jump, spec, texels, file);
  jpeg_destroy_compress(&cinfo);
  std::fclose(file);
  REQUIRE(written);
}

// Every texel of `decoded` against OpenImageIO's reading of the same file (rt::read_image: float
// RGB, grey replicated, what its TextureSystem looked up): the same values.
void check_against_openimageio(const rt::DecodedImage& decoded, const fs::path& path) {
  const std::optional<rt::Image> reference = rt::read_image(path.string());
  REQUIRE(reference->width == decoded.layout.width);
  REQUIRE(reference->height == decoded.layout.height);
  int mismatches = 0;
  float worst = 0.0f;
  for (int y = 0; y < decoded.layout.height; ++y)
    for (int x = 0; x < decoded.layout.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const float ours = decoded.channel(x, y, decoded.layout.channels <= 2 ? 0 : c);
        const float theirs = reference->at(x, y)[c];
        const float difference = std::abs(ours - theirs);
        worst = std::max(worst, difference);
        if (difference > 1e-6f) ++mismatches;
      }
  INFO(path.string() << ": worst difference " << worst);
  CHECK(mismatches == 0);
}

rt::DecodedImage decode_file(const fs::path& path) {
  std::string error;
  std::optional<rt::DecodedImage> image = rt::decode_image(rt_test::read_file(path), error);
  INFO(path.string() << ": " << error);
  REQUIRE(image);
  return *image;
}

}  // namespace

TEST_CASE("PNG decoding gives every colour type and bit depth as libpng wrote it and as OpenImageIO reads it", "[decode]") {
  const TempDir dir;
  struct Case {
    const char* name;
    PngSpec spec;
    int channels, bits;
  };
  const Case cases[] = {
      {"rgb8", {7, 5, PNG_COLOR_TYPE_RGB, 8, false}, 3, 8},
      {"rgba8", {7, 5, PNG_COLOR_TYPE_RGB_ALPHA, 8, false}, 4, 8},
      {"grey8", {7, 5, PNG_COLOR_TYPE_GRAY, 8, false}, 1, 8},
      {"grey-alpha8", {7, 5, PNG_COLOR_TYPE_GRAY_ALPHA, 8, false}, 2, 8},
      {"grey1", {13, 3, PNG_COLOR_TYPE_GRAY, 1, false}, 1, 8},
      {"grey4", {9, 4, PNG_COLOR_TYPE_GRAY, 4, false}, 1, 8},
      {"palette-trns", {9, 6, PNG_COLOR_TYPE_PALETTE, 4, false}, 4, 8},
      {"rgb16", {6, 5, PNG_COLOR_TYPE_RGB, 16, false}, 3, 16},
      {"rgba16-interlaced", {11, 9, PNG_COLOR_TYPE_RGB_ALPHA, 16, true}, 4, 16},
      {"rgb8-interlaced", {17, 10, PNG_COLOR_TYPE_RGB, 8, true}, 3, 8},
  };
  for (const Case& c : cases) {
    SECTION(c.name) {
      const fs::path path = dir.path() / (std::string(c.name) + ".png");
      write_test_png(path, c.spec);
      const rt::DecodedImage image = decode_file(path);
      REQUIRE(image.layout.width == c.spec.width);
      REQUIRE(image.layout.height == c.spec.height);
      REQUIRE(image.layout.channels == c.channels);
      REQUIRE(image.layout.bits == c.bits);
      std::string error;
      const auto layout = rt::read_image_layout(rt_test::read_file(path), error);
      REQUIRE(layout);
      CHECK(layout->channels == c.channels);
      // The values libpng was given (grey and 16-bit samples directly; palette entries through
      // their PLTE colour and tRNS alpha).
      const int depth = c.spec.color_type == PNG_COLOR_TYPE_PALETTE ? 4 : c.spec.depth;
      const float full = float((1u << depth) - 1);
      for (int y = 0; y < c.spec.height; ++y)
        for (int x = 0; x < c.spec.width; ++x) {
          const int i = y * c.spec.width + x;
          if (c.spec.color_type == PNG_COLOR_TYPE_PALETTE) {
            const unsigned k = pattern(i, 0, 4);
            CHECK(image.channel(x, y, 0) == Approx(float(k * 16) / 255.0f).margin(1e-7));
            CHECK(image.channel(x, y, 1) == Approx(float(255 - k * 8) / 255.0f).margin(1e-7));
            CHECK(image.channel(x, y, 3) == Approx(float(k * 17) / 255.0f).margin(1e-7));
          } else {
            for (int ch = 0; ch < c.channels; ++ch)  // low depths scale up exactly (v * 255 / full)
              CHECK(image.channel(x, y, ch) == Approx(float(pattern(i, ch, depth)) / full).margin(1e-6));
          }
        }
      check_against_openimageio(image, path);
    }
  }
}

TEST_CASE("JPEG decoding gives the texels OpenImageIO reads, baseline, progressive, subsampled and grey", "[decode]") {
  const TempDir dir;
  const std::pair<const char*, JpegSpec> cases[] = {
      {"baseline-420", {33, 21, 3, false, 2, 2}},
      {"baseline-444", {16, 16, 3, false, 1, 1}},
      {"progressive-422", {40, 17, 3, true, 2, 1}},
      {"grey", {19, 23, 1, false, 1, 1}},
  };
  for (const auto& [name, spec] : cases) {
    SECTION(name) {
      const fs::path path = dir.path() / (std::string(name) + ".jpg");
      write_test_jpeg(path, spec);
      const rt::DecodedImage image = decode_file(path);
      CHECK(image.layout.width == spec.width);
      CHECK(image.layout.height == spec.height);
      CHECK(image.layout.channels == spec.components);
      check_against_openimageio(image, path);
    }
  }
}

TEST_CASE("Every PNG and JPEG of the shared sample models decodes to the texels OpenImageIO reads", "[decode]") {
  const fs::path models = fs::path(RT_SHARED_DATA_DIR) / "data/models";
  if (!fs::is_directory(models)) {
    WARN("sample models not found at " << models.string() << " (RT_SHARED_DATA_DIR): skipping");
    return;
  }
  std::set<std::pair<std::uintmax_t, std::string>> seen;  // (size, name): the samples repeat images across variants
  int checked = 0;
  for (const auto& entry : fs::recursive_directory_iterator(models)) {
    std::string extension = entry.path().extension().string();
    for (char& ch : extension) ch = char(std::tolower(static_cast<unsigned char>(ch)));
    if (extension != ".png" && extension != ".jpg" && extension != ".jpeg") continue;
    if (!seen.emplace(entry.file_size(), entry.path().filename().string()).second) continue;
    check_against_openimageio(decode_file(entry.path()), entry.path());
    ++checked;
  }
  CHECK(checked > 10);
}

TEST_CASE("Damaged PNG and JPEG bytes are refused with the decoder's reason, never a crash", "[decode]") {
  const TempDir dir;
  write_test_png(dir.path() / "a.png", {64, 64, PNG_COLOR_TYPE_RGB, 8, false});
  write_test_jpeg(dir.path() / "a.jpg", {64, 64, 3, false, 2, 2});
  for (const char* name : {"a.png", "a.jpg"}) {
    const std::string bytes = rt_test::read_file(dir.path() / name);
    std::string error;
    // Cut inside the header: neither the layout nor the image.
    CHECK_FALSE(rt::read_image_layout(std::string_view(bytes).substr(0, 20), error));
    CHECK_FALSE(error.empty());
    error.clear();
    CHECK_FALSE(rt::decode_image(std::string_view(bytes).substr(0, 20), error));
    CHECK_FALSE(error.empty());
    // Not an image at all.
    error.clear();
    CHECK_FALSE(rt::decode_image("GIF89a....", error));
    CHECK(error == "neither a PNG nor a JPEG");
  }
  // A PNG cut inside its image data: the layout reads, the image does not.
  const std::string png = rt_test::read_file(dir.path() / "a.png");
  std::string error;
  CHECK(rt::read_image_layout(std::string_view(png).substr(0, png.size() / 2), error));
  CHECK_FALSE(rt::decode_image(std::string_view(png).substr(0, png.size() / 2), error));
  CHECK(error.find("truncated") != std::string::npos);
  // Corrupt image data (zlib stream bytes flipped).
  std::string corrupt = png;
  for (std::size_t i = 60; i < 90 && i < corrupt.size(); ++i) corrupt[i] = char(~corrupt[i]);
  error.clear();
  CHECK_FALSE(rt::decode_image(corrupt, error));
  CHECK_FALSE(error.empty());
}

TEST_CASE("Bilinear lookups of decoded textures match OpenImageIO's TextureSystem for every wrap mode", "[decode][texture]") {
  const TempDir dir;
  write_test_png(dir.path() / "rgb.png", {7, 5, PNG_COLOR_TYPE_RGB, 8, false});
  write_test_png(dir.path() / "grey-alpha.png", {6, 9, PNG_COLOR_TYPE_GRAY_ALPHA, 8, false});
  write_test_png(dir.path() / "rgb16.png", {5, 4, PNG_COLOR_TYPE_RGB, 16, false});
  write_test_jpeg(dir.path() / "photo.jpg", {33, 21, 3, false, 2, 2});
  const rt::TextureWrap wraps[] = {rt::TextureWrap::repeat, rt::TextureWrap::clamp_to_edge,
                                   rt::TextureWrap::mirrored_repeat};
  rt::Scene scene;
  for (const char* file : {"rgb.png", "grey-alpha.png", "rgb16.png", "photo.jpg"})
    for (rt::TextureWrap s : wraps)
      for (rt::TextureWrap t : wraps) {
        rt::Material m;
        m.diffuse_texture.path = (dir.path() / file).string();
        m.diffuse_texture.wrap_s = s;
        m.diffuse_texture.wrap_t = t;
        scene.materials.push_back(m);
      }
  const rt::TextureSampler ours(scene);
  const rt::TextureSampler theirs(scene, /*cache_bytes=*/1);  // too small: every texture through OpenImageIO
  CHECK(ours.use().decoded == 4);
  CHECK_FALSE(ours.use().tiled);
  CHECK(ours.use().through_oiio == 0);
  CHECK(theirs.use().tiled);
  CHECK(theirs.use().decoded == 0);
  CHECK(theirs.use().through_oiio == int(scene.materials.size()));
  std::mt19937 random(20261202);
  std::uniform_real_distribution<float> coordinate(-2.5f, 3.5f);
  float worst = 0.0f;
  for (std::uint32_t m = 0; m < scene.materials.size(); ++m)
    for (int k = 0; k < 200; ++k) {
      // Random points, and a lattice of points with some on texel edges, where wrap modes differ most.
      rt::TexCoords uv;
      uv.uv0 = k % 4 == 0 ? rt::Vec2f(float(k % 23 - 9) / 7.0f, float(k % 17 - 6) / 5.0f)
                          : rt::Vec2f(coordinate(random), coordinate(random));
      const rt::Vec3f a = ours.sample(m, rt::TextureRole::diffuse, uv), b = theirs.sample(m, rt::TextureRole::diffuse, uv);
      const float difference = std::max({std::abs(a.x - b.x), std::abs(a.y - b.y), std::abs(a.z - b.z)});
      if (difference >= 2e-5f && worst < 2e-5f)  // the first mismatch, to say where
        UNSCOPED_INFO(scene.materials[m].diffuse_texture.path << " wraps " << int(scene.materials[m].diffuse_texture.wrap_s)
                      << "," << int(scene.materials[m].diffuse_texture.wrap_t) << " at (" << uv.uv0.x << ", " << uv.uv0.y
                      << "): rt (" << a.x << ", " << a.y << ", " << a.z << "), OpenImageIO (" << b.x << ", " << b.y
                      << ", " << b.z << ")");
      worst = std::max(worst, difference);
    }
  // OpenImageIO computes the texel position in single precision (st * width - 0.5f); rt in double.
  CHECK(worst < 2e-5f);
}

TEST_CASE("A texture cache smaller than the textures sends them through OpenImageIO tiles and says so", "[decode][texture][cli]") {
  const TempDir dir;
  write_test_png(dir.path() / "checker.png", {64, 48, PNG_COLOR_TYPE_RGB, 8, false});
  rt_test::write_file(dir.path() / "quad.mtl", "newmtl textured\nKd 1 1 1\nmap_Kd checker.png\n");
  rt_test::write_file(dir.path() / "quad.obj",
                      "mtllib quad.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                      "usemtl textured\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n");
  const std::string common = "render --width 48 --height 36 --eye 0 0 2.5 --target 0 0 0 quad.obj";
  const rt_test::RtRun usual = rt_test::run_rt_in(dir, common + " -o usual.png --stats usual.json");
  REQUIRE(usual.status == 0);
  CHECK(usual.err.find("texture cache") == std::string::npos);
  // 64 x 48 RGB texels decoded are 9216 bytes; 4K does not hold them.
  const rt_test::RtRun bounded = rt_test::run_rt_in(dir, common + " -o bounded.png --stats bounded.json --texture-cache 4K");
  REQUIRE(bounded.status == 0);
  CHECK(bounded.err.find("rt: note: the PNG and JPEG textures take 9.0 KiB decoded, more than the 4.0 KiB texture cache") !=
        std::string::npos);
  const auto stats = [&](const char* name) { return nlohmann::json::parse(rt_test::read_file(dir.path() / name))["textures"]; };
  CHECK(stats("usual.json")["decoded"] == 1);
  CHECK(stats("usual.json")["tiled"] == false);
  CHECK(stats("bounded.json")["tiled"] == true);
  CHECK(stats("bounded.json")["through_openimageio"] == 1);
  CHECK(stats("bounded.json")["cache_bytes"] == 4096);
  // The same image, to the 8-bit rounding of lookups that agree to 2e-5.
  const rt::Image a = rt::read_image((dir.path() / "usual.png").string());
  const rt::Image b = rt::read_image((dir.path() / "bounded.png").string());
  float worst = 0.0f, textured = 0.0f;
  for (std::size_t i = 0; i < a.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      worst = std::max(worst, std::abs(a.pixels[i][c] - b.pixels[i][c]));
      textured = std::max(textured, a.pixels[i][c]);
    }
  CHECK(worst <= 1.0f / 255.0f);
  CHECK(textured > 0.1f);  // the quad is in view and lit
  // A malformed size is refused before anything is loaded.
  const rt_test::RtRun bad = rt_test::run_rt_in(dir, common + " --texture-cache lots");
  CHECK(bad.status == 2);
  CHECK(bad.err.find("'lots' is not a size such as 512M or 8G") != std::string::npos);
}
