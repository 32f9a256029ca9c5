#include "tests/testing/exif_jpeg.h"

#include <cstdlib>
#include <cstring>
#include <stdexcept>

#include <libexif/exif-data.h>
#include <opencv2/imgcodecs.hpp>

namespace flysfm {
namespace testing {

std::vector<std::uint8_t> JpegWithExif(const cv::Mat& image, const ExifTags& tags) {
  ExifData* exif = exif_data_new();
  exif_data_set_byte_order(exif, EXIF_BYTE_ORDER_INTEL);
  for (const auto& [tag, value] : tags.numbers) {
    ExifEntry* entry = exif_entry_new();
    exif_content_add_entry(exif->ifd[EXIF_IFD_EXIF], entry);
    exif_entry_initialize(entry, tag);
    if (entry->format == EXIF_FORMAT_SHORT) {
      exif_set_short(entry->data, EXIF_BYTE_ORDER_INTEL, ExifShort(value));
    } else if (entry->format == EXIF_FORMAT_LONG) {
      exif_set_long(entry->data, EXIF_BYTE_ORDER_INTEL, ExifLong(value));
    } else {
      exif_set_rational(entry->data, EXIF_BYTE_ORDER_INTEL,
                        ExifRational{ExifLong(value * 1000), 1000});
    }
    exif_entry_unref(entry);
  }
  for (const auto& [tag, text] : tags.texts) {
    ExifEntry* entry = exif_entry_new();
    const bool ifd0 = tag == EXIF_TAG_MAKE || tag == EXIF_TAG_MODEL;
    exif_content_add_entry(exif->ifd[ifd0 ? EXIF_IFD_0 : EXIF_IFD_EXIF], entry);
    entry->tag = tag;
    entry->format = EXIF_FORMAT_ASCII;
    entry->components = text.size() + 1;
    entry->size = static_cast<unsigned int>(text.size() + 1);
    // libexif frees an entry's data with its default allocator, free().
    entry->data = static_cast<unsigned char*>(std::malloc(entry->size));
    std::memcpy(entry->data, text.c_str(), entry->size);
    exif_entry_unref(entry);
  }
  unsigned char* block = nullptr;
  unsigned int length = 0;
  exif_data_save_data(exif, &block, &length);
  exif_data_unref(exif);
  if (block == nullptr) throw std::runtime_error("libexif wrote no EXIF block");
  std::vector<std::uint8_t> jpeg;
  if (!cv::imencode(".jpg", image, jpeg)) throw std::runtime_error("JPEG encoding failed");
  // APP1 right after the start-of-image marker; its length counts itself.
  std::vector<std::uint8_t> app1 = {0xFF, 0xE1, std::uint8_t((length + 2) >> 8),
                                    std::uint8_t((length + 2) & 0xFF)};
  app1.insert(app1.end(), block, block + length);
  std::free(block);
  jpeg.insert(jpeg.begin() + 2, app1.begin(), app1.end());
  return jpeg;
}

std::vector<std::uint8_t> WithoutExif(const std::vector<std::uint8_t>& jpeg) {
  if (jpeg.size() < 4 || jpeg[0] != 0xFF || jpeg[1] != 0xD8) {
    throw std::invalid_argument("not a JPEG");
  }
  std::vector<std::uint8_t> out = {0xFF, 0xD8};
  std::size_t at = 2;
  // Marker segments up to the first scan; everything from there is copied.
  while (at + 4 <= jpeg.size() && jpeg[at] == 0xFF && jpeg[at + 1] != 0xDA) {
    const std::size_t length = std::size_t(jpeg[at + 2]) << 8 | jpeg[at + 3];
    if (length < 2 || at + 2 + length > jpeg.size()) throw std::invalid_argument("bad JPEG segment");
    if (jpeg[at + 1] != 0xE1) out.insert(out.end(), jpeg.begin() + at, jpeg.begin() + at + 2 + length);
    at += 2 + length;
  }
  if (at + 2 > jpeg.size() || jpeg[at] != 0xFF) throw std::invalid_argument("no JPEG scan");
  out.insert(out.end(), jpeg.begin() + at, jpeg.end());
  return out;
}

}  // namespace testing
}  // namespace flysfm
