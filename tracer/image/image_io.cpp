// Reading and writing image files: PNG/EXR export through an atomic temp-file-and-rename writer,
// and loading of PNG/JPEG/HDR (stb_image) and OpenEXR (tinyexr) into linear float RGB.
#include <fcntl.h>
#include <stb_image.h>
#include <stb_image_write.h>
#include <sys/stat.h>
#include <tinyexr.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "core/diagnostics.h"
#include "image/image.h"

namespace tracer {
namespace {

namespace fs = std::filesystem;

// Anything larger is a corrupt header or a mistake, not a render: 64k per side and 2^27 pixels
// (1.5 GiB as float RGB) keep a hostile header from making us allocate without bound.
constexpr long long kMaxImageSide = 65536;
constexpr long long kMaxImagePixels = 1LL << 27;
constexpr const char* kNotSaved = "the file was not written";
constexpr const char* kNotLoaded = "the image was not loaded";

[[noreturn]] void fail(const std::string& path, const std::string& problem, const char* action) {
  throw InputError(SourceLoc{path, 0}, problem, action);
}

// Creates the folders of `path` that are missing and returns its folder ("" for a bare name).
fs::path make_parent_directories(const std::string& path, const char* action) {
  const fs::path dir = fs::path(path).parent_path();
  if (!dir.empty()) {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec || !fs::is_directory(dir)) {
      const std::string why = ec ? ec.message() : std::string("not a directory");
      fail(path, "cannot create directory '" + dir.string() + "': " + why, action);
    }
  }
  return dir;
}

std::string lower_extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

bool write_all(int fd, const unsigned char* data, size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    data += n;
    size -= static_cast<size_t>(n);
  }
  return true;
}

// Writes `size` bytes to `path` so that readers see either the old file or the complete new one:
// write a uniquely named temporary beside the target (rename() is only atomic within one file
// system), fsync it so a crash cannot leave the rename pointing at unwritten blocks, then rename.
void write_bytes_atomic(const std::string& path, const void* data, size_t size) {
  const fs::path target(path);
  if (!target.has_filename()) fail(path, "is not a file name", kNotSaved);
  const fs::path dir = make_parent_directories(path, kNotSaved);

  // Name: hidden, derived from the target (shortened to stay under NAME_MAX), made unique by the
  // pid and a counter so that concurrent writers in one or several processes never collide.
  static std::atomic<unsigned> counter{0};
  const std::string stem = target.filename().string().substr(0, 200);
  std::string tmp;
  int fd = -1;
  for (int attempt = 0; attempt < 100 && fd < 0; ++attempt) {
    const std::string name = "." + stem + ".tmp." + std::to_string(::getpid()) + "." +
                             std::to_string(counter.fetch_add(1));
    tmp = (dir / name).string();
    // 0666 lets the umask decide the final permissions, as for any newly created file.
    fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0 && errno != EEXIST) break;
  }
  if (fd < 0)
    fail(path, std::string("cannot create a temporary file: ") + std::strerror(errno), kNotSaved);

  std::string problem;
  if (!write_all(fd, static_cast<const unsigned char*>(data), size)) {
    problem = std::string("write failed: ") + std::strerror(errno);
  } else if (::fsync(fd) != 0 && errno != EINVAL && errno != EROFS) {
    // EINVAL/EROFS: the file system (e.g. a pipe-like special file) does not support fsync.
    problem = std::string("fsync failed: ") + std::strerror(errno);
  }
  if (::close(fd) != 0 && problem.empty()) {
    problem = std::string("close failed: ") + std::strerror(errno);
  }
  if (problem.empty() && std::rename(tmp.c_str(), path.c_str()) != 0) {
    problem = std::string("cannot replace the target: ") + std::strerror(errno);
  }
  if (!problem.empty()) {
    ::unlink(tmp.c_str());
    fail(path, problem, "the file was not written and any existing file is unchanged");
  }
}

void append_bytes(void* context, void* data, int size) {
  auto* out = static_cast<std::vector<unsigned char>*>(context);
  const auto* bytes = static_cast<const unsigned char*>(data);
  out->insert(out->end(), bytes, bytes + size);
}

std::vector<unsigned char> encode_png(const std::string& path, const ImageRGB& img,
                                      float exposure_stops, ToneMap op) {
  const float scale = std::exp2(exposure_stops);
  std::vector<unsigned char> rgb8(img.pixels.size());
  for (size_t i = 0; i < img.pixels.size(); i += 3) {
    const vec3 c = tone_map(scale * vec3(img.pixels[i], img.pixels[i + 1], img.pixels[i + 2]), op);
    for (int k = 0; k < 3; ++k) rgb8[i + k] = to_srgb8(c[k]);
  }
  std::vector<unsigned char> png;
  if (!stbi_write_png_to_func(append_bytes, &png, img.width, img.height, 3, rgb8.data(),
                              3 * img.width)) {
    fail(path, "PNG encoding failed", kNotSaved);
  }
  return png;
}

std::vector<unsigned char> encode_exr_channels(const std::string& path, int width, int height,
                                               std::vector<ExrChannel> channels) {
  // OpenEXR stores channels planar and viewers expect them sorted by name (B, G, R, ...).
  std::sort(channels.begin(), channels.end(),
            [](const ExrChannel& a, const ExrChannel& b) { return a.name < b.name; });
  const size_t n = static_cast<size_t>(width) * height;
  const int count = int(channels.size());
  std::vector<unsigned char*> images(channels.size());
  std::vector<EXRChannelInfo> infos(channels.size());
  std::vector<int> pixel_types(channels.size(), TINYEXR_PIXELTYPE_FLOAT);
  // Full float32, no conversion to half.
  std::vector<int> requested_types(channels.size(), TINYEXR_PIXELTYPE_FLOAT);
  for (int c = 0; c < count; ++c) {
    if (channels[c].values.size() != n || channels[c].name.empty() ||
        channels[c].name.size() >= sizeof(infos[c].name))
      fail(path, "OpenEXR channel '" + channels[c].name + "' has the wrong size or name", kNotSaved);
    std::memset(&infos[c], 0, sizeof(infos[c]));
    std::memcpy(infos[c].name, channels[c].name.c_str(), channels[c].name.size());
    images[c] = reinterpret_cast<unsigned char*>(channels[c].values.data());
  }
  EXRImage image;
  InitEXRImage(&image);
  image.images = images.data();
  image.num_channels = count;
  image.width = width;
  image.height = height;

  EXRHeader header;
  InitEXRHeader(&header);
  header.num_channels = count;
  header.channels = infos.data();
  header.pixel_types = pixel_types.data();
  header.requested_pixel_types = requested_types.data();
  // As in tinyexr's own SaveEXR: tiny images are stored uncompressed.
  header.compression_type = (width < 16 && height < 16) ? TINYEXR_COMPRESSIONTYPE_NONE
                                                        : TINYEXR_COMPRESSIONTYPE_ZIP;

  unsigned char* memory = nullptr;
  const char* err = nullptr;
  const size_t size = SaveEXRImageToMemory(&image, &header, &memory, &err);
  // `header` points at our arrays, so it is deliberately not passed to FreeEXRHeader.
  if (size == 0 || memory == nullptr) {
    const std::string why = err ? err : "unknown error";
    if (err) FreeEXRErrorMessage(err);
    std::free(memory);
    fail(path, "OpenEXR encoding failed: " + why, kNotSaved);
  }
  std::vector<unsigned char> out(memory, memory + size);
  std::free(memory);
  return out;
}

std::vector<ExrChannel> rgb_channels(const ImageRGB& img, const std::string& prefix) {
  const size_t n = static_cast<size_t>(img.width) * img.height;
  std::vector<ExrChannel> out(3);
  for (int c = 0; c < 3; ++c) {
    out[c].name = prefix + "RGB"[c];
    out[c].values.resize(n);
    for (size_t i = 0; i < n; ++i) out[c].values[i] = img.pixels[3 * i + c];
  }
  return out;
}

std::vector<unsigned char> encode_exr(const std::string& path, const ImageRGB& img) {
  return encode_exr_channels(path, img.width, img.height, rgb_channels(img, ""));
}

std::vector<unsigned char> read_file(const std::string& path) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (st.type() == fs::file_type::not_found) fail(path, "file not found", kNotLoaded);
  if (fs::is_directory(st)) fail(path, "is a directory, not an image", kNotLoaded);
  FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) fail(path, std::string("cannot open: ") + std::strerror(errno), kNotLoaded);
  std::vector<unsigned char> bytes;
  unsigned char chunk[1 << 16];
  size_t n;
  while ((n = std::fread(chunk, 1, sizeof(chunk), f)) > 0) {
    bytes.insert(bytes.end(), chunk, chunk + n);
    // stb_image takes an int length; a bigger file is not an image we could decode anyway.
    if (bytes.size() > static_cast<size_t>(INT_MAX)) {
      std::fclose(f);
      fail(path, "file is too large to be an image", kNotLoaded);
    }
  }
  const bool error = std::ferror(f);
  std::fclose(f);
  if (error) fail(path, "read error", kNotLoaded);
  if (bytes.empty()) fail(path, "file is empty", kNotLoaded);
  return bytes;
}

void check_size(const std::string& path, long long w, long long h) {
  if (w <= 0 || h <= 0 || w > kMaxImageSide || h > kMaxImageSide || w * h > kMaxImagePixels) {
    fail(path,
         "image size " + std::to_string(w) + "x" + std::to_string(h) + " is empty or too large",
         kNotLoaded);
  }
}

ImageRGB decode_stb(const std::string& path, const std::vector<unsigned char>& bytes) {
  const int len = static_cast<int>(bytes.size());
  int w = 0, h = 0, comp = 0;
  if (!stbi_info_from_memory(bytes.data(), len, &w, &h, &comp)) {
    fail(path, std::string("not a readable PNG/JPEG/HDR/EXR image (") + stbi_failure_reason() + ")",
         kNotLoaded);
  }
  check_size(path, w, h);

  ImageRGB img = make_image(w, h);
  const size_t count = img.pixels.size();
  // Ask stb for 3 channels: it expands grey and drops alpha (we ignore transparency).
  if (stbi_is_hdr_from_memory(bytes.data(), len)) {
    float* data = stbi_loadf_from_memory(bytes.data(), len, &w, &h, &comp, 3);
    if (!data) fail(path, std::string("corrupt image: ") + stbi_failure_reason(), kNotLoaded);
    std::copy(data, data + count, img.pixels.begin());  // Radiance HDR is already linear
    stbi_image_free(data);
  } else if (stbi_is_16_bit_from_memory(bytes.data(), len)) {
    stbi_us* data = stbi_load_16_from_memory(bytes.data(), len, &w, &h, &comp, 3);
    if (!data) fail(path, std::string("corrupt image: ") + stbi_failure_reason(), kNotLoaded);
    for (size_t i = 0; i < count; ++i) img.pixels[i] = srgb_to_linear(data[i] / 65535.0f);
    stbi_image_free(data);
  } else {
    stbi_uc* data = stbi_load_from_memory(bytes.data(), len, &w, &h, &comp, 3);
    if (!data) fail(path, std::string("corrupt image: ") + stbi_failure_reason(), kNotLoaded);
    float lut[256];
    for (int v = 0; v < 256; ++v) lut[v] = srgb_to_linear(v / 255.0f);
    for (size_t i = 0; i < count; ++i) img.pixels[i] = lut[data[i]];
    stbi_image_free(data);
  }
  return img;
}

// Owns a parsed header; tinyexr's C API needs explicit frees on every path.
struct ExrHeaderOwner {
  EXRHeader header;
  ExrHeaderOwner() { InitEXRHeader(&header); }
  ~ExrHeaderOwner() { FreeEXRHeader(&header); }
};

[[noreturn]] void fail_exr(const std::string& path, const std::string& what, const char* err) {
  const std::string why = err ? std::string(": ") + err : std::string();
  if (err) FreeEXRErrorMessage(err);
  fail(path, what + why, kNotLoaded);
}

float exr_value(const unsigned char* plane, int pixel_type, size_t index) {
  if (pixel_type == TINYEXR_PIXELTYPE_UINT) {
    return static_cast<float>(reinterpret_cast<const uint32_t*>(plane)[index]);
  }
  return reinterpret_cast<const float*>(plane)[index];
}

ImageRGB decode_exr(const std::string& path, const std::vector<unsigned char>& bytes) {
  EXRVersion version;
  if (ParseEXRVersionFromMemory(&version, bytes.data(), bytes.size()) != TINYEXR_SUCCESS) {
    fail(path, "not a valid OpenEXR file", kNotLoaded);
  }
  if (version.multipart || version.non_image) {
    fail(path, "multi-part and deep OpenEXR files are not supported", kNotLoaded);
  }
  ExrHeaderOwner owner;
  EXRHeader& header = owner.header;
  const char* err = nullptr;
  if (ParseEXRHeaderFromMemory(&header, &version, bytes.data(), bytes.size(), &err) !=
      TINYEXR_SUCCESS) {
    fail_exr(path, "corrupt OpenEXR header", err);
  }
  // Check before decoding: the data window alone decides how much tinyexr allocates.
  check_size(path, 1LL + header.data_window.max_x - header.data_window.min_x,
             1LL + header.data_window.max_y - header.data_window.min_y);

  int source[3] = {-1, -1, -1};  // R, G, B channel indices
  for (int c = 0; c < header.num_channels; ++c) {
    const std::string name = header.channels[c].name;
    if (name == "R") source[0] = c;
    if (name == "G") source[1] = c;
    if (name == "B") source[2] = c;
    if (header.pixel_types[c] == TINYEXR_PIXELTYPE_HALF) {
      header.requested_pixel_types[c] = TINYEXR_PIXELTYPE_FLOAT;
    }
  }
  if (header.num_channels == 1) {
    source[0] = source[1] = source[2] = 0;  // a single (e.g. Y) channel is shown as grey
  } else if (source[0] < 0 || source[1] < 0 || source[2] < 0) {
    std::string names;
    for (int c = 0; c < header.num_channels; ++c) {
      names += std::string(c ? ", " : "") + header.channels[c].name;
    }
    fail(path, "OpenEXR file has no R, G and B channels (found: " + names + ")", kNotLoaded);
  }

  EXRImage exr;
  InitEXRImage(&exr);
  // tinyexr 1.0.1 sets num_channels only after a scanline image decodes, so its own cleanup of a
  // failed decode would leak every channel buffer; setting it first lets that cleanup free them.
  exr.num_channels = header.num_channels;
  if (LoadEXRImageFromMemory(&exr, &header, bytes.data(), bytes.size(), &err) != TINYEXR_SUCCESS) {
    // tinyexr has already freed the partial image on this path; freeing it again would crash.
    fail_exr(path, "corrupt OpenEXR data", err);
  }
  check_size(path, exr.width, exr.height);
  ImageRGB img = make_image(exr.width, exr.height);
  if (exr.tiles) {
    // Only the finest level of a mip/rip-mapped file: the tiles of `exr` itself.
    for (int t = 0; t < exr.num_tiles; ++t) {
      const EXRTile& tile = exr.tiles[t];
      for (int j = 0; j < tile.height; ++j) {
        for (int i = 0; i < tile.width; ++i) {
          const int x = tile.offset_x * header.tile_size_x + i;
          const int y = tile.offset_y * header.tile_size_y + j;
          if (x >= img.width || y >= img.height) continue;
          const size_t src = static_cast<size_t>(j) * header.tile_size_x + i;
          vec3 v;
          for (int c = 0; c < 3; ++c) {
            v[c] = exr_value(tile.images[source[c]], header.requested_pixel_types[source[c]], src);
          }
          img.set(x, y, v);
        }
      }
    }
  } else if (exr.images) {
    const size_t n = static_cast<size_t>(img.width) * img.height;
    for (size_t i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) {
        img.pixels[3 * i + c] =
            exr_value(exr.images[source[c]], header.requested_pixel_types[source[c]], i);
      }
    }
  }
  FreeEXRImage(&exr);
  return img;
}

bool is_exr(const std::vector<unsigned char>& bytes) {
  // OpenEXR magic number 20000630 as little-endian bytes.
  return bytes.size() >= 4 && bytes[0] == 0x76 && bytes[1] == 0x2f && bytes[2] == 0x31 &&
         bytes[3] == 0x01;
}

}  // namespace

void write_image(const std::string& path, const ImageRGB& img, float exposure_stops, ToneMap op) {
  const std::string ext = lower_extension(path);
  if (ext != ".png" && ext != ".exr") {
    fail(path, "unknown image extension '" + ext + "' (expected .png or .exr)", kNotSaved);
  }
  if (img.width <= 0 || img.height <= 0 ||
      img.pixels.size() != 3 * static_cast<size_t>(img.width) * img.height) {
    fail(path,
         "image is empty or inconsistent (" + std::to_string(img.width) + "x" +
             std::to_string(img.height) + ", " + std::to_string(img.pixels.size()) + " floats)",
         kNotSaved);
  }
  if (static_cast<long long>(img.width) * img.height > kMaxImagePixels) {
    fail(path, "image is too large to export", kNotSaved);
  }
  const std::vector<unsigned char> bytes =
      ext == ".png" ? encode_png(path, img, exposure_stops, op) : encode_exr(path, img);
  write_bytes_atomic(path, bytes.data(), bytes.size());
}

void write_exr_layers(const std::string& path, const ImageRGB& img,
                      std::vector<ExrChannel> layers) {
  if (lower_extension(path) != ".exr") fail(path, "layers need an .exr file", kNotSaved);
  if (img.width <= 0 || img.height <= 0 ||
      img.pixels.size() != 3 * static_cast<size_t>(img.width) * img.height)
    fail(path, "image is empty or inconsistent", kNotSaved);
  std::vector<ExrChannel> channels = rgb_channels(img, "");
  for (ExrChannel& l : layers) channels.push_back(std::move(l));
  const std::vector<unsigned char> bytes =
      encode_exr_channels(path, img.width, img.height, std::move(channels));
  write_bytes_atomic(path, bytes.data(), bytes.size());
}

void write_png_rgba8(const std::string& path, int width, int height, const uint8_t* rgba,
                     bool bottom_up) {
  std::vector<unsigned char> png;
  const int stride = 4 * width;
  const unsigned char* first = rgba + (bottom_up ? size_t(height - 1) * stride : 0);
  if (!stbi_write_png_to_func(append_bytes, &png, width, height, 4, first,
                              bottom_up ? -stride : stride)) {
    fail(path, "PNG encoding failed", kNotSaved);
  }
  write_bytes_atomic(path, png.data(), png.size());
}

void check_writable(const std::string& path) {
  const fs::path target(path);
  if (!target.has_filename()) fail(path, "is not a file name", "nothing was rendered");
  const fs::path dir = make_parent_directories(path, "nothing was rendered");
  // The same kind of temporary file the atomic writer makes, made and removed at once.
  const std::string tmp = (dir / ("." + target.filename().string().substr(0, 200) + ".check." +
                                  std::to_string(::getpid())))
                              .string();
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) {
    fail(path, std::string("cannot be written: ") + std::strerror(errno), "nothing was rendered");
  }
  ::close(fd);
  ::unlink(tmp.c_str());
}

void write_text_atomic(const std::string& path, const std::string& text) {
  write_bytes_atomic(path, text.data(), text.size());
}

ImageRGB read_image(const std::string& path) {
  const std::vector<unsigned char> bytes = read_file(path);
  return is_exr(bytes) ? decode_exr(path, bytes) : decode_stb(path, bytes);
}

}  // namespace tracer
