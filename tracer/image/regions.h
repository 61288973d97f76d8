// Where an image comparison looks: the regions it reports statistics for, and the pixels it
// leaves out (a mask image, rectangles). A region source only labels pixels, so a grid today and
// an object-ID image (once the renderer writes one) feed the same per-region statistics.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "image/image.h"

namespace tracer {

// A pixel rectangle, half-open: x0 <= x < x1, y0 <= y < y1, row 0 at the top.
struct PixelRect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  long area() const { return long(x1 - x0) * long(y1 - y0); }
  std::string str() const;  // "x0,y0,x1,y1", the form --exclude reads
};

// Every pixel's region. Labels index `regions`; kNoRegion pixels belong to none. Today's source
// is a grid; an ID image (a per-pixel object index, planned with the AOVs) would give one region
// per object ID with its name and bounding box, and nothing downstream changes.
struct RegionMap {
  static constexpr int32_t kNoRegion = -1;
  struct Region {
    std::string name;           // the grid's "column,row"; an object's name for an ID image
    PixelRect box;              // bounding box of the region's pixels
    int column = -1, row = -1;  // grid cell; -1 for other sources
  };
  int width = 0, height = 0;
  std::vector<int32_t> label;  // width * height, row-major, top row first
  std::vector<Region> regions;
  std::string source;  // "grid 4x4", "image": for reports
};

// `columns` x `rows` cells of (nearly) equal size: cell i spans [floor(i W / n), floor((i+1) W /
// n)). Throws InputError when a count is below 1 or above the image's size in that direction.
RegionMap grid_regions(int width, int height, int columns, int rows);
// One region, "image", holding every pixel.
RegionMap whole_image_region(int width, int height);
// Reads "NxM" (columns x rows, e.g. "4x4"); false when malformed.
bool parse_grid(const std::string& text, int* columns, int* rows);
// Reads "x0,y0,x1,y1" (whole numbers, x0 < x1, y0 < y1); false when malformed.
bool parse_rect(const std::string& text, PixelRect* rect);

// The pixels a comparison keeps, and why the others are gone.
struct PixelMask {
  struct Exclusion {
    std::string what;  // "mask FILE", "exclude x0,y0,x1,y1"
    long pixels = 0;   // pixels it removes (overlaps with other exclusions counted in each)
  };
  int width = 0, height = 0;
  std::vector<uint8_t> keep;  // width * height; 1 = compared
  std::vector<Exclusion> exclusions;
  long kept() const;
};

// Keeps every pixel.
PixelMask full_mask(int width, int height);
// Removes the pixels where `mask` (read from `path`) is not above 0 in any channel (0, negative
// or NaN everywhere); PNG, EXR or anything read_image reads. Throws InputError naming both sizes
// when the mask's size differs from the images'.
void apply_mask_image(PixelMask* m, const ImageRGB& mask, const std::string& path);
// Removes a rectangle, clipped to the image; throws InputError when it lies wholly outside.
void apply_exclude_rect(PixelMask* m, const PixelRect& r);

// Throws InputError "NAME is WxH but REF_NAME is WxH; nothing was compared" when sizes differ.
void require_same_size(const ImageRGB& img, const std::string& name, int width, int height,
                       const std::string& ref_name);

}  // namespace tracer
