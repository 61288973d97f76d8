// Open Image Denoise through dlopen: the library, one device and one filter kept between calls
// (the viewport denoises the same size again and again; a new filter costs a commit).
#include "image/denoise.h"

#include <dlfcn.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cstdlib>
#include <mutex>
#include <stdexcept>
#include <vector>

namespace tracer {
namespace {

// The parts of OIDN's C API (include/OpenImageDenoise/oidn.h, version 2) called here.
using OIDNDevice = struct OIDNDeviceImpl*;
using OIDNFilter = struct OIDNFilterImpl*;
using OIDNBuffer = struct OIDNBufferImpl*;
constexpr int kOidnDeviceDefault = 0, kOidnDeviceCpu = 1, kOidnDeviceCuda = 3;
constexpr int kOidnFormatFloat3 = 3;

struct OidnApi {
  OIDNDevice (*NewDevice)(int type);
  void (*CommitDevice)(OIDNDevice);
  void (*ReleaseDevice)(OIDNDevice);
  int (*GetDeviceInt)(OIDNDevice, const char*);
  int (*GetDeviceError)(OIDNDevice, const char**);
  OIDNBuffer (*NewBuffer)(OIDNDevice, size_t);
  void (*WriteBuffer)(OIDNBuffer, size_t, size_t, const void*);
  void (*ReadBuffer)(OIDNBuffer, size_t, size_t, void*);
  void (*ReleaseBuffer)(OIDNBuffer);
  OIDNFilter (*NewFilter)(OIDNDevice, const char*);
  void (*SetFilterImage)(OIDNFilter, const char*, OIDNBuffer, int, size_t, size_t, size_t, size_t,
                         size_t);
  void (*SetSharedFilterImage)(OIDNFilter, const char*, void*, int, size_t, size_t, size_t, size_t,
                               size_t);
  void (*UnsetFilterImage)(OIDNFilter, const char*);
  void (*SetFilterBool)(OIDNFilter, const char*, bool);
  void (*CommitFilter)(OIDNFilter);
  void (*ExecuteFilter)(OIDNFilter);
  void (*ReleaseFilter)(OIDNFilter);
};

std::string exe_dir() {
  char buf[PATH_MAX];
  const ssize_t len = readlink("/proc/self/exe", buf, sizeof(buf) - 1);
  if (len <= 0) return ".";
  std::string p(buf, size_t(len));
  const size_t slash = p.rfind('/');
  return slash == std::string::npos ? "." : p.substr(0, slash);
}

const char* device_type_name(int type) {
  switch (type) {
    case 1: return "CPU";
    case 2: return "SYCL";
    case 3: return "CUDA";
    case 4: return "HIP";
    case 5: return "Metal";
    default: return "unknown";
  }
}

struct Oidn {
  std::mutex mutex;
  bool tried = false;
  void* lib = nullptr;
  OidnApi api{};
  OIDNDevice device = nullptr;
  std::string status;  // what was loaded, or why nothing was
  std::string version, device_name;
  // The cached filter and its buffers: for this size and these inputs.
  OIDNFilter filter = nullptr;
  OIDNBuffer buf_color = nullptr, buf_albedo = nullptr, buf_normal = nullptr, buf_out = nullptr;
  int width = 0, height = 0;
  bool has_albedo = false, has_normal = false;
  // The filter on device images (denoise_device_images) and the pointers it was committed with.
  OIDNFilter dev_filter = nullptr;
  const void* dev_ptrs[4] = {nullptr, nullptr, nullptr, nullptr};
  int dev_width = 0, dev_height = 0;

  void release_filter() {
    if (filter) api.ReleaseFilter(filter);
    for (OIDNBuffer* b : {&buf_color, &buf_albedo, &buf_normal, &buf_out}) {
      if (*b) api.ReleaseBuffer(*b);
      *b = nullptr;
    }
    filter = nullptr;
    width = height = 0;
  }

  std::string error() {
    const char* msg = nullptr;
    if (api.GetDeviceError(device, &msg) == 0) return {};
    return msg ? msg : "unknown error";
  }

  template <typename Fn>
  bool bind(Fn*& fn, const char* name) {
    fn = reinterpret_cast<Fn*>(dlsym(lib, name));
    return fn != nullptr;
  }

  // Under the mutex.
  void load() {
    if (tried) return;
    tried = true;
    // TRACER_OIDN_LIBRARY (the library or its folder) is the only place tried when set.
    std::vector<std::string> candidates;
    if (const char* env = std::getenv("TRACER_OIDN_LIBRARY")) {
      std::string p = env;
      if (!p.empty() && p.back() == '/') p.pop_back();
      if (p.find(".so") == std::string::npos) p += "/libOpenImageDenoise.so.2";
      candidates.push_back(p);
    } else {
#ifdef TRACER_OIDN_DIR
      candidates.push_back(std::string(TRACER_OIDN_DIR) + "/libOpenImageDenoise.so.2");
#endif
      candidates.push_back(exe_dir() + "/lib/libOpenImageDenoise.so.2");
      candidates.push_back("libOpenImageDenoise.so.2");  // the system's search path
    }
    std::string tried_list;
    for (const std::string& c : candidates) {
      lib = dlopen(c.c_str(), RTLD_NOW | RTLD_LOCAL);
      if (lib) {
        status = c;
        break;
      }
      const char* why = dlerror();
      tried_list += "\n  " + c + ": " + (why ? why : "not loadable");
    }
    if (!lib) {
      status = "Open Image Denoise not found (scripts/setup.sh installs it from PyPI's pyoidn "
               "into .deps/oidn; TRACER_OIDN_LIBRARY names another copy). Tried:" +
               tried_list;
      return;
    }
    const bool ok = bind(api.NewDevice, "oidnNewDevice") &&
                    bind(api.CommitDevice, "oidnCommitDevice") &&
                    bind(api.ReleaseDevice, "oidnReleaseDevice") &&
                    bind(api.GetDeviceInt, "oidnGetDeviceInt") &&
                    bind(api.GetDeviceError, "oidnGetDeviceError") &&
                    bind(api.NewBuffer, "oidnNewBuffer") &&
                    bind(api.WriteBuffer, "oidnWriteBuffer") &&
                    bind(api.ReadBuffer, "oidnReadBuffer") &&
                    bind(api.ReleaseBuffer, "oidnReleaseBuffer") &&
                    bind(api.NewFilter, "oidnNewFilter") &&
                    bind(api.SetFilterImage, "oidnSetFilterImage") &&
                    bind(api.SetSharedFilterImage, "oidnSetSharedFilterImage") &&
                    bind(api.UnsetFilterImage, "oidnUnsetFilterImage") &&
                    bind(api.SetFilterBool, "oidnSetFilterBool") &&
                    bind(api.CommitFilter, "oidnCommitFilter") &&
                    bind(api.ExecuteFilter, "oidnExecuteFilter") &&
                    bind(api.ReleaseFilter, "oidnReleaseFilter");
    if (!ok) {
      status = status + " lacks the OIDN 2 C API";
      dlclose(lib);
      lib = nullptr;
      return;
    }
    // TRACER_OIDN_DEVICE=cpu|cuda chooses; by default OIDN takes the fastest it supports.
    int type = kOidnDeviceDefault;
    if (const char* env = std::getenv("TRACER_OIDN_DEVICE")) {
      const std::string d = env;
      if (d == "cpu") type = kOidnDeviceCpu;
      if (d == "cuda") type = kOidnDeviceCuda;
    }
    device = api.NewDevice(type);
    if (!device) {
      status = "Open Image Denoise (" + status + ") has no usable device";
      return;
    }
    api.CommitDevice(device);
    const std::string err = error();
    if (!err.empty()) {
      status = "Open Image Denoise (" + status + "): " + err;
      api.ReleaseDevice(device);
      device = nullptr;
      return;
    }
    const int v = api.GetDeviceInt(device, "version");  // e.g. 20501
    version = std::to_string(v / 10000) + "." + std::to_string(v / 100 % 100) + "." +
              std::to_string(v % 100);
    device_name = device_type_name(api.GetDeviceInt(device, "type"));
    status = "Open Image Denoise " + version + " (" + device_name + " device), " + status;
  }
};

Oidn& oidn() {
  static Oidn o;  // never destroyed before exit's own unloading matters: the OS frees it
  return o;
}

void check_size(const ImageRGB& img, const ImageRGB& color, const char* what) {
  if (img.width != color.width || img.height != color.height ||
      img.pixels.size() != color.pixels.size())
    throw std::runtime_error(std::string("denoise: the ") + what + " image is " +
                             std::to_string(img.width) + "x" + std::to_string(img.height) +
                             ", the colour " + std::to_string(color.width) + "x" +
                             std::to_string(color.height));
}

}  // namespace

bool denoiser_available() {
  Oidn& o = oidn();
  std::lock_guard<std::mutex> lock(o.mutex);
  o.load();
  return o.device != nullptr;
}

std::string denoiser_status() {
  Oidn& o = oidn();
  std::lock_guard<std::mutex> lock(o.mutex);
  o.load();
  return o.status;
}

ImageRGB denoise_image(const ImageRGB& color, const ImageRGB* albedo, const ImageRGB* normal,
                       DenoiseInfo* info) {
  const auto start = std::chrono::steady_clock::now();
  if (color.width <= 0 || color.height <= 0 ||
      color.pixels.size() != size_t(color.width) * color.height * 3)
    throw std::runtime_error("denoise: the colour image is empty or inconsistent");
  if (albedo && albedo->pixels.empty()) albedo = nullptr;
  if (normal && (normal->pixels.empty() || !albedo)) normal = nullptr;
  if (albedo) check_size(*albedo, color, "albedo");
  if (normal) check_size(*normal, color, "normal");
  Oidn& o = oidn();
  std::lock_guard<std::mutex> lock(o.mutex);
  o.load();
  if (!o.device) throw std::runtime_error(o.status);
  const OidnApi& api = o.api;
  const size_t w = size_t(color.width), h = size_t(color.height);
  const size_t bytes = w * h * 3 * sizeof(float);
  if (!o.filter || o.width != color.width || o.height != color.height ||
      o.has_albedo != (albedo != nullptr) || o.has_normal != (normal != nullptr)) {
    o.release_filter();
    o.filter = api.NewFilter(o.device, "RT");
    o.buf_color = api.NewBuffer(o.device, bytes);
    o.buf_out = api.NewBuffer(o.device, bytes);
    if (albedo) o.buf_albedo = api.NewBuffer(o.device, bytes);
    if (normal) o.buf_normal = api.NewBuffer(o.device, bytes);
    std::string err = o.error();
    if (!err.empty() || !o.filter) {
      o.release_filter();
      throw std::runtime_error("denoise: Open Image Denoise: " + err);
    }
    api.SetFilterImage(o.filter, "color", o.buf_color, kOidnFormatFloat3, w, h, 0, 0, 0);
    if (albedo) api.SetFilterImage(o.filter, "albedo", o.buf_albedo, kOidnFormatFloat3, w, h, 0, 0, 0);
    if (normal) api.SetFilterImage(o.filter, "normal", o.buf_normal, kOidnFormatFloat3, w, h, 0, 0, 0);
    api.SetFilterImage(o.filter, "output", o.buf_out, kOidnFormatFloat3, w, h, 0, 0, 0);
    api.SetFilterBool(o.filter, "hdr", true);
    api.CommitFilter(o.filter);
    err = o.error();
    if (!err.empty()) {
      o.release_filter();
      throw std::runtime_error("denoise: Open Image Denoise: " + err);
    }
    o.width = color.width;
    o.height = color.height;
    o.has_albedo = albedo != nullptr;
    o.has_normal = normal != nullptr;
  }
  api.WriteBuffer(o.buf_color, 0, bytes, color.pixels.data());
  if (albedo) api.WriteBuffer(o.buf_albedo, 0, bytes, albedo->pixels.data());
  if (normal) api.WriteBuffer(o.buf_normal, 0, bytes, normal->pixels.data());
  api.ExecuteFilter(o.filter);
  ImageRGB out;
  out.width = color.width;
  out.height = color.height;
  out.pixels.resize(color.pixels.size());
  api.ReadBuffer(o.buf_out, 0, bytes, out.pixels.data());
  const std::string err = o.error();
  if (!err.empty()) {
    o.release_filter();
    throw std::runtime_error("denoise: Open Image Denoise: " + err);
  }
  if (info) {
    info->denoiser = "Open Image Denoise " + o.version;
    info->device = o.device_name;
    info->inputs = std::string("color") + (albedo ? "+albedo" : "") + (normal ? "+normal" : "");
    info->ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                   .count();
  }
  return out;
}

bool denoise_device_images(const float* color, const float* albedo, const float* normal,
                           float* out, int width, int height, DenoiseInfo* info) {
  const auto start = std::chrono::steady_clock::now();
  Oidn& o = oidn();
  std::lock_guard<std::mutex> lock(o.mutex);
  o.load();
  if (!o.device) throw std::runtime_error(o.status);
  if (o.device_name != "CUDA") return false;
  if (!albedo) normal = nullptr;
  const OidnApi& api = o.api;
  const size_t w = size_t(width), h = size_t(height);
  const void* ptrs[4] = {color, albedo, normal, out};
  if (!o.dev_filter || o.dev_width != width || o.dev_height != height ||
      !std::equal(ptrs, ptrs + 4, o.dev_ptrs)) {
    if (o.dev_filter) api.ReleaseFilter(o.dev_filter);
    o.dev_filter = api.NewFilter(o.device, "RT");
    auto set = [&](const char* name, const void* p) {
      api.SetSharedFilterImage(o.dev_filter, name, const_cast<void*>(p), kOidnFormatFloat3, w, h,
                               0, 0, 0);
    };
    set("color", color);
    if (albedo) set("albedo", albedo);
    if (normal) set("normal", normal);
    set("output", out);
    api.SetFilterBool(o.dev_filter, "hdr", true);
    api.CommitFilter(o.dev_filter);
    const std::string err = o.error();
    if (!err.empty()) {
      api.ReleaseFilter(o.dev_filter);
      o.dev_filter = nullptr;
      throw std::runtime_error("denoise: Open Image Denoise: " + err);
    }
    std::copy(ptrs, ptrs + 4, o.dev_ptrs);
    o.dev_width = width;
    o.dev_height = height;
  }
  api.ExecuteFilter(o.dev_filter);
  const std::string err = o.error();
  if (!err.empty()) throw std::runtime_error("denoise: Open Image Denoise: " + err);
  if (info) {
    info->denoiser = "Open Image Denoise " + o.version;
    info->device = o.device_name + ", in device memory";
    info->inputs = std::string("color") + (albedo ? "+albedo" : "") + (normal ? "+normal" : "");
    info->ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                   .count();
  }
  return true;
}

}  // namespace tracer
