// Region sources (a grid) and pixel exclusions (mask image, rectangles) for image comparisons.
#include "image/regions.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/diagnostics.h"

namespace tracer {
namespace {

std::string size_str(int w, int h) {
  return std::to_string(w) + "x" + std::to_string(h);
}

// Reads a whole number (optionally signed) from text[*pos...]; false when none.
bool read_int(const std::string& text, size_t* pos, int* out) {
  size_t i = *pos;
  bool negative = false;
  if (i < text.size() && (text[i] == '-' || text[i] == '+')) negative = text[i++] == '-';
  long v = 0;
  const size_t digits = i;
  while (i < text.size() && text[i] >= '0' && text[i] <= '9' && v < 1000000000L)
    v = v * 10 + (text[i++] - '0');
  if (i == digits || (i < text.size() && text[i] >= '0' && text[i] <= '9')) return false;
  *out = static_cast<int>(negative ? -v : v);
  *pos = i;
  return true;
}

}  // namespace

std::string PixelRect::str() const {
  return std::to_string(x0) + "," + std::to_string(y0) + "," + std::to_string(x1) + "," +
         std::to_string(y1);
}

RegionMap grid_regions(int width, int height, int columns, int rows) {
  if (columns < 1 || rows < 1 || columns > width || rows > height) {
    throw InputError(SourceLoc{"--grid", 0},
                     "a " + size_str(columns, rows) + " grid does not fit a " +
                         size_str(width, height) + " image (1 to " + std::to_string(width) +
                         " columns, 1 to " + std::to_string(height) + " rows)",
                     "nothing was compared");
  }
  RegionMap map;
  map.width = width;
  map.height = height;
  map.source = "grid " + size_str(columns, rows);
  map.label.assign(size_t(width) * height, RegionMap::kNoRegion);
  auto edge = [](int i, int size, int n) { return int(long(i) * size / n); };
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < columns; ++c) {
      RegionMap::Region region;
      region.name = std::to_string(c) + "," + std::to_string(r);
      region.column = c;
      region.row = r;
      region.box = {edge(c, width, columns), edge(r, height, rows), edge(c + 1, width, columns),
                    edge(r + 1, height, rows)};
      const int32_t id = static_cast<int32_t>(map.regions.size());
      for (int y = region.box.y0; y < region.box.y1; ++y)
        for (int x = region.box.x0; x < region.box.x1; ++x) map.label[size_t(y) * width + x] = id;
      map.regions.push_back(region);
    }
  }
  return map;
}

RegionMap whole_image_region(int width, int height) {
  RegionMap map;
  map.width = width;
  map.height = height;
  map.source = "image";
  map.label.assign(size_t(width) * height, 0);
  RegionMap::Region region;
  region.name = "image";
  region.box = {0, 0, width, height};
  map.regions.push_back(region);
  return map;
}

bool parse_grid(const std::string& text, int* columns, int* rows) {
  size_t pos = 0;
  int c = 0, r = 0;
  if (!read_int(text, &pos, &c) || pos >= text.size() || (text[pos] != 'x' && text[pos] != 'X'))
    return false;
  ++pos;
  if (!read_int(text, &pos, &r) || pos != text.size()) return false;
  *columns = c;
  *rows = r;
  return true;
}

bool parse_rect(const std::string& text, PixelRect* rect) {
  int v[4];
  size_t pos = 0;
  for (int i = 0; i < 4; ++i) {
    if (i > 0) {
      if (pos >= text.size() || text[pos] != ',') return false;
      ++pos;
    }
    if (!read_int(text, &pos, &v[i])) return false;
  }
  if (pos != text.size() || v[0] >= v[2] || v[1] >= v[3]) return false;
  *rect = {v[0], v[1], v[2], v[3]};
  return true;
}

long PixelMask::kept() const {
  long n = 0;
  for (uint8_t k : keep) n += k;
  return n;
}

PixelMask full_mask(int width, int height) {
  PixelMask m;
  m.width = width;
  m.height = height;
  m.keep.assign(size_t(width) * height, 1);
  return m;
}

void apply_mask_image(PixelMask* m, const ImageRGB& mask, const std::string& path) {
  if (mask.width != m->width || mask.height != m->height) {
    throw InputError(SourceLoc{path, 0},
                     "the mask is " + size_str(mask.width, mask.height) + " but the images are " +
                         size_str(m->width, m->height),
                     "nothing was compared");
  }
  PixelMask::Exclusion ex{"mask " + path, 0};
  for (size_t i = 0; i < m->keep.size(); ++i) {
    const float* p = &mask.pixels[3 * i];
    if (!(p[0] > 0.0f || p[1] > 0.0f || p[2] > 0.0f)) {
      m->keep[i] = 0;
      ++ex.pixels;
    }
  }
  m->exclusions.push_back(ex);
}

void apply_exclude_rect(PixelMask* m, const PixelRect& r) {
  const PixelRect c{std::max(r.x0, 0), std::max(r.y0, 0), std::min(r.x1, m->width),
                    std::min(r.y1, m->height)};
  if (c.x0 >= c.x1 || c.y0 >= c.y1) {
    throw InputError(SourceLoc{"--exclude " + r.str(), 0},
                     "the rectangle lies outside the " + size_str(m->width, m->height) + " image",
                     "nothing was compared");
  }
  PixelMask::Exclusion ex{"exclude " + r.str(), c.area()};
  for (int y = c.y0; y < c.y1; ++y)
    for (int x = c.x0; x < c.x1; ++x) m->keep[size_t(y) * m->width + x] = 0;
  m->exclusions.push_back(ex);
}

void require_same_size(const ImageRGB& img, const std::string& name, int width, int height,
                       const std::string& ref_name) {
  if (img.width == width && img.height == height) return;
  throw InputError(SourceLoc{"image comparison", 0},
                   name + " is " + size_str(img.width, img.height) + " but " + ref_name + " is " +
                       size_str(width, height),
                   "nothing was compared");
}

}  // namespace tracer
