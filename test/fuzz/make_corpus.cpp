// Writes the seed corpus (test/fuzz/corpus/<target>/) and the reproducers of the bugs the
// fuzzing found (test/fuzz/regressions/<target>/): small valid inputs and one of each kind of
// fault. Usage: fuzz_make_corpus <test/fuzz folder>. scripts/fuzz.sh runs it before fuzzing;
// the files are checked in and replayed by the fuzz_replay_* tests.
#include <png.h>
#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "fuzz_input.h"
#include "gmm_mcl/camera/png_io.h"
#include "gmm_mcl/map/gmm_map_io.h"

namespace gmm_mcl {
namespace {

using Bytes = std::vector<uint8_t>;

std::string g_root;

void makeDir(const std::string& path) { mkdir(path.c_str(), 0755); }

void write(const std::string& kind, const std::string& target, const std::string& name,
           const Bytes& bytes) {
  makeDir(g_root + "/" + kind);
  makeDir(g_root + "/" + kind + "/" + target);
  const std::string path = g_root + "/" + kind + "/" + target + "/" + name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
  if (!out) {
    std::fprintf(stderr, "%s: cannot write\n", path.c_str());
    std::exit(1);
  }
}

void putU32(Bytes* b, size_t at, uint32_t v) {
  for (int k = 0; k < 4; ++k) (*b)[at + k] = static_cast<uint8_t>(v >> (8 * k));
}
void putF32(Bytes* b, size_t at, float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  putU32(b, at, u);
}
void put(Bytes* b, size_t at, uint32_t v) { putU32(b, at, v); }
void put(Bytes* b, size_t at, float f) { putF32(b, at, f); }
void fixCrc(Bytes* b) { putU32(b, b->size() - 4, crc32(b->data(), b->size() - 4)); }

// ---- map files ------------------------------------------------------------------------------
GmmMap mapOf(int m) {
  std::vector<GaussianComponent> comps(m);
  for (int i = 0; i < m; ++i) {
    comps[i].weight = 1.0 / m;
    comps[i].mean_m = Eigen::Vector3d(0.5 * i, -0.25 * i, 1.0 + 0.1 * i);
    comps[i].cov_m2 << 0.04, 0.01, 0.0, 0.01, 0.02, 0.005, 0.0, 0.005, 0.01 + 0.001 * i;
  }
  return GmmMap(comps);
}

void mapCorpus() {
  const std::string t = "map_loader";
  const Bytes one = encodeMap(mapOf(1)), three = encodeMap(mapOf(3));
  write("corpus", t, "valid_m1.gmm", one);
  write("corpus", t, "valid_m3.gmm", three);
  Bytes b = three;
  b[0] = 'X';
  write("corpus", t, "bad_magic.gmm", b);
  write("corpus", t, "truncated_header.gmm", Bytes(three.begin(), three.begin() + 20));
  write("corpus", t, "truncated_payload.gmm", Bytes(three.begin(), three.end() - 9));
  b = three;
  b.push_back(0);
  write("corpus", t, "trailing_byte.gmm", b);
  b = three;
  b[40] ^= 1;
  write("corpus", t, "bad_crc.gmm", b);
  // The M=3 map with one word changed and the checksum made right again.
  const auto changed = [&](const char* name, size_t at, auto value) {
    Bytes c = three;
    put(&c, at, value);
    fixCrc(&c);
    write("corpus", t, name, c);
  };
  changed("version_2.gmm", 8, uint32_t{2});
  changed("scalar_type_2.gmm", 16, uint32_t{2});
  b = Bytes(three.begin(), three.begin() + kMapHeaderBytes);
  putU32(&b, 12, 0);
  b.resize(b.size() + 4);
  fixCrc(&b);
  write("corpus", t, "zero_count.gmm", b);
  changed("nan_weight.gmm", kMapHeaderBytes + 4, std::numeric_limits<float>::quiet_NaN());
  changed("negative_weight.gmm", kMapHeaderBytes, -1.f / 3);
  changed("weights_not_one.gmm", kMapHeaderBytes, 0.5f);
  const size_t cov0 = kMapHeaderBytes + 16 * 3;  // after 3 weights and 3 means
  changed("not_positive_definite.gmm", cov0, -0.04f);
  changed("inf_covariance.gmm", cov0 + 4, std::numeric_limits<float>::infinity());
  // Bug: a positive-definite covariance of denormal floats passed every check, and its inverse
  // (1e39) was packed as a float: a map with infinite precisions loaded without an error.
  b = one;
  const float tiny = 1e-39f;
  const size_t c1 = kMapHeaderBytes + 16;
  for (int k = 0; k < 6; ++k) putF32(&b, c1 + 4 * k, (k == 0 || k == 3 || k == 5) ? tiny : 0.f);
  fixCrc(&b);
  write("regressions", t, "denormal_covariance_float_overflow.gmm", b);
}

// ---- depth frames -------------------------------------------------------------------------
// What closes every depth_frame input: the frame parameters, then the image or cloud data.
struct FrameTail {
  int32_t stride = 1, patch = 4;
  double min_range = 0.1, max_range = 4.0;
  Bytes data;
};

void writeTail(const FrameTail& c, fuzz::Writer* w) {
  w->i32(c.stride);
  w->i32(c.patch);
  w->number(c.min_range);
  w->number(c.max_range);
  w->raw(c.data);
}

struct ImageCase : FrameTail {
  std::string encoding = "16UC1";
  uint32_t width = 8, height = 6, step = 16;
  bool big_endian = false;
  double K[9] = {6.0, 0.0, 3.5, 0.0, 6.0, 2.5, 0.0, 0.0, 1.0};
  uint32_t info_width = 8, info_height = 6;
};

Bytes imageInput(const ImageCase& c) {
  fuzz::Writer w;
  w.u8(0);
  w.u8(7);  // the encoding as a string
  w.str(c.encoding);
  for (uint32_t size : {c.width, c.height, c.step}) w.u32(size);
  w.u8(c.big_endian ? 1 : 0);
  for (double k : c.K) w.number(k);
  w.u32(c.info_width);
  w.u32(c.info_height);
  writeTail(c, &w);
  return w.bytes;
}

// h rows of row_step bytes; pixel(u, v, p) writes pixel (u, v) at p, pixel_step bytes apart.
template <typename Pixel>
Bytes rows(uint32_t w, uint32_t h, uint32_t row_step, uint32_t pixel_step, Pixel pixel) {
  Bytes d(static_cast<size_t>(row_step) * h, 0);
  for (uint32_t v = 0; v < h; ++v) {
    for (uint32_t u = 0; u < w; ++u) pixel(u, v, &d[v * row_step + u * pixel_step]);
  }
  return d;
}

Bytes millimetres(uint32_t w, uint32_t h, uint32_t step, bool big_endian) {
  return rows(w, h, step, 2, [big_endian](uint32_t u, uint32_t v, uint8_t* p) {
    const uint16_t mm = (u + v) % 5 == 0 ? 0 : static_cast<uint16_t>(500 + 300 * u + 100 * v);
    p[big_endian ? 1 : 0] = static_cast<uint8_t>(mm & 0xFF);
    p[big_endian ? 0 : 1] = static_cast<uint8_t>(mm >> 8);
  });
}

Bytes metres(uint32_t w, uint32_t h, bool big_endian) {
  Bytes d(static_cast<size_t>(4) * w * h, 0);
  for (uint32_t i = 0; i < w * h; ++i) {
    float z = i % 7 == 0 ? std::numeric_limits<float>::quiet_NaN() : 0.05f + 0.3f * (i % 17);
    uint8_t b[4];
    std::memcpy(b, &z, 4);
    for (int k = 0; k < 4; ++k) d[4 * i + k] = b[big_endian ? 3 - k : k];
  }
  return d;
}

struct CloudCase : FrameTail {
  CloudCase() { stride = 2; }
  uint32_t width = 8, height = 6, point_step = 16, row_step = 128;
  bool big_endian = false;
  int32_t x = 0, y = 4, z = 8;
};

Bytes cloudInput(const CloudCase& c) {
  fuzz::Writer w;
  w.u8(1);
  for (uint32_t size : {c.width, c.height, c.point_step, c.row_step}) w.u32(size);
  w.u8(c.big_endian ? 1 : 0);
  for (int32_t offset : {c.x, c.y, c.z}) w.i32(offset);  // of the x, y, z fields
  writeTail(c, &w);
  return w.bytes;
}

// Points of a pinhole camera (f = 6, c = (3.5, 2.5)) looking at a tilted plane.
Bytes cloudPoints(uint32_t w, uint32_t h, uint32_t point_step, uint32_t row_step) {
  return rows(w, h, row_step, point_step, [](uint32_t u, uint32_t v, uint8_t* out) {
    const float z = 1.0f + 0.1f * u + 0.05f * v;
    float p[3] = {(u - 3.5f) * z / 6.f, (v - 2.5f) * z / 6.f, z};
    if ((u * 7 + v) % 11 == 0) p[2] = std::numeric_limits<float>::quiet_NaN();
    std::memcpy(out, p, 12);
  });
}

void depthFrameCorpus() {
  const std::string t = "depth_frame";
  ImageCase c;
  c.data = millimetres(8, 6, 16, false);
  write("corpus", t, "image_16uc1.bin", imageInput(c));
  // c with one fault, written as folder/depth_frame/name.
  const auto image = [&](const char* folder, const char* name, void (*fault)(ImageCase&)) {
    ImageCase bad = c;
    fault(bad);
    write(folder, t, name, imageInput(bad));
  };
  ImageCase m = c;
  m.encoding = "mono16";
  m.step = 20;
  m.big_endian = true;
  m.stride = 2;
  m.patch = 3;
  m.data = millimetres(8, 6, 20, true);
  write("corpus", t, "image_mono16_big_endian_padded.bin", imageInput(m));
  ImageCase f = c;
  f.encoding = "32FC1";
  f.step = 32;
  f.data = metres(8, 6, false);
  write("corpus", t, "image_32fc1.bin", imageInput(f));
  f.big_endian = true;
  f.data = metres(8, 6, true);
  f.patch = 32;
  write("corpus", t, "image_32fc1_big_endian.bin", imageInput(f));
  image("corpus", "image_bad_encoding.bin", [](ImageCase& bad) { bad.encoding = "rgb8"; });
  image("corpus", "image_short_step.bin", [](ImageCase& bad) { bad.step = 15; });
  image("corpus", "image_short_data.bin", [](ImageCase& bad) { bad.data.resize(50); });
  image("corpus", "image_size_mismatch.bin", [](ImageCase& bad) { bad.info_width = 16; });
  image("corpus", "camera_uncalibrated.bin", [](ImageCase& bad) {
    for (double& k : bad.K) k = 0.0;
  });
  image("corpus", "camera_nan.bin",
        [](ImageCase& bad) { bad.K[0] = std::numeric_limits<double>::quiet_NaN(); });
  image("corpus", "params_bad.bin", [](ImageCase& bad) {
    bad.stride = 0;
    bad.min_range = 5.0;
  });

  // Bugs: K values a float cannot hold were accepted (fx = 1e300 became an infinite focal
  // length, fy = 1e-300 passed the positivity check and became 0, cx = 3e38 gave infinite
  // points); patch sizes and strides near INT_MAX overflowed int in prepareFrame (UB).
  image("regressions", "camera_fx_1e300.bin", [](ImageCase& bad) { bad.K[0] = 1e300; });
  image("regressions", "camera_fy_1e-300.bin", [](ImageCase& bad) { bad.K[4] = 1e-300; });
  image("regressions", "camera_cx_-1e300.bin", [](ImageCase& bad) { bad.K[2] = -1e300; });
  image("regressions", "camera_cx_3e38_infinite_points.bin",
        [](ImageCase& bad) { bad.K[2] = 3e38; });
  image("regressions", "params_patch_int_max.bin",
        [](ImageCase& bad) { bad.patch = std::numeric_limits<int32_t>::max(); });
  image("regressions", "params_stride_int_max.bin", [](ImageCase& bad) {
    bad.stride = std::numeric_limits<int32_t>::max();
    bad.patch = 3;
  });

  CloudCase cl;
  cl.data = cloudPoints(8, 6, 16, 128);
  write("corpus", t, "cloud_8x6.bin", cloudInput(cl));
  // cl with one fault, written as folder/depth_frame/name.
  const auto cloud = [&](const char* folder, const char* name, void (*fault)(CloudCase&)) {
    CloudCase bad = cl;
    fault(bad);
    write(folder, t, name, cloudInput(bad));
  };
  cloud("corpus", "cloud_unorganized.bin", [](CloudCase& bad) { bad.height = 1; });
  cloud("corpus", "cloud_no_z.bin", [](CloudCase& bad) { bad.z = -1; });
  cloud("corpus", "cloud_short_data.bin", [](CloudCase& bad) { bad.data.resize(100); });
  // Bugs: a field offset beyond the point read past the data (heap overflow), and
  // width x point_step wrapped around 32 bits, so a short row passed the layout check.
  cloud("regressions", "cloud_field_offset_beyond_point.bin", [](CloudCase& bad) { bad.z = 100; });
  cloud("regressions", "cloud_row_step_wraps_32_bits.bin", [](CloudCase& bad) {
    bad.width = 1u << 28;
    bad.point_step = 16;  // 2^32: wraps to 0 in uint32
    bad.row_step = 16;
    bad.height = 2;
    bad.data.resize(64);
  });
}

// ---- compressedDepth ------------------------------------------------------------------------
Bytes compressedInput(uint8_t format_sel, const Bytes& data) {
  fuzz::Writer w;
  w.u8(format_sel);
  w.raw(data);
  return w.bytes;
}

Bytes compressed(const DepthImage& img) {
  std::string format, error;
  Bytes data;
  if (!encodeCompressedDepth(img, &format, &data, &error)) {
    std::fprintf(stderr, "encode: %s\n", error.c_str());
    std::exit(1);
  }
  return data;
}

// An 8-bit grey PNG (libpng's simplified API), behind a compressedDepth header.
Bytes eightBitPng() {
  png_image img{};
  img.version = PNG_IMAGE_VERSION;
  img.width = 4;
  img.height = 3;
  img.format = PNG_FORMAT_GRAY;
  const uint8_t pixels[12] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
  png_alloc_size_t size = 0;
  png_image_write_to_memory(&img, nullptr, &size, 0, pixels, 0, nullptr);
  Bytes png(size);
  png_image_write_to_memory(&img, png.data(), &size, 0, pixels, 0, nullptr);
  png.resize(size);
  Bytes out(12, 0);
  out.insert(out.end(), png.begin(), png.end());
  return out;
}

void compressedCorpus() {
  const std::string t = "compressed_depth";
  std::vector<uint16_t> mm(6 * 4);
  for (size_t i = 0; i < mm.size(); ++i)
    mm[i] = i % 5 == 0 ? 0 : static_cast<uint16_t>(700 + 97 * i);
  const Bytes c16 = compressed(DepthImage::fromMillimetres(6, 4, mm));
  write("corpus", t, "valid_16uc1.bin", compressedInput(0, c16));
  std::vector<float> m(5 * 3);
  for (size_t i = 0; i < m.size(); ++i) {
    m[i] = i % 4 == 0 ? std::numeric_limits<float>::quiet_NaN() : 0.3f + 0.5f * i;
  }
  const Bytes c32 = compressed(DepthImage::fromMetres(5, 3, m));
  write("corpus", t, "valid_32fc1.bin", compressedInput(1, c32));
  write("corpus", t, "valid_mono16_no_png_suffix.bin", compressedInput(3, c16));
  write("corpus", t, "truncated_png.bin", compressedInput(0, Bytes(c16.begin(), c16.end() - 20)));
  write("corpus", t, "header_only.bin", compressedInput(0, Bytes(c16.begin(), c16.begin() + 12)));
  write("corpus", t, "rvl.bin", compressedInput(4, c16));
  write("corpus", t, "not_compressed.bin", compressedInput(5, c16));
  write("corpus", t, "eight_bit_png.bin", compressedInput(0, eightBitPng()));
  Bytes nanq = c32;
  putF32(&nanq, 4, std::numeric_limits<float>::quiet_NaN());
  write("corpus", t, "nan_quantisation.bin", compressedInput(1, nanq));
  // Bug: a PNG header claiming 10^6 x 10^6 pixels made the decoder allocate (and zero) 2 TB
  // before reading a row. IHDR: width at PNG byte 16, height at 20, its CRC at 29.
  Bytes huge = c16;
  const size_t ihdr = 12 + 8;  // compressedDepth header, PNG signature
  for (size_t at : {ihdr + 8, ihdr + 12}) {
    const uint32_t v = 1000000;
    huge[at] = static_cast<uint8_t>(v >> 24);
    huge[at + 1] = static_cast<uint8_t>(v >> 16);
    huge[at + 2] = static_cast<uint8_t>(v >> 8);
    huge[at + 3] = static_cast<uint8_t>(v);
  }
  const uint32_t crc = crc32(&huge[ihdr + 4], 4 + 13);
  for (int k = 0; k < 4; ++k) huge[ihdr + 21 + k] = static_cast<uint8_t>(crc >> (24 - 8 * k));
  write("regressions", t, "png_claims_1e6_by_1e6.bin", compressedInput(0, huge));
}

}  // namespace
}  // namespace gmm_mcl

int main(int argc, char** argv) {
  using namespace gmm_mcl;
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <test/fuzz folder>\n", argv[0]);
    return 2;
  }
  g_root = argv[1];
  mapCorpus();
  depthFrameCorpus();
  compressedCorpus();
  std::printf("corpus and regressions written under %s\n", g_root.c_str());
  return 0;
}
