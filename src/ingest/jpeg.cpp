#include "chronomap/ingest/jpeg.h"

// jpeglib.h needs FILE and size_t declared first.
#include <cstddef>
#include <cstdio>

#include <jpeglib.h>

#include <algorithm>
#include <csetjmp>
#include <cstdlib>
#include <cstring>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/png.h"
#include "setjmp_message.h"

namespace chronomap {

namespace {

/// Bytes of decoded image allowed per byte of file, and the least allowance: real colour
/// frames compress 5 to 50 times; a few hundred bytes declaring 32768 x 32768 is a bomb.
constexpr uint64_t kMaxExpansion = 4096;
constexpr uint64_t kMinAllowance = uint64_t{64} << 20;

struct ErrorManager {
  jpeg_error_mgr base;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX] = {0};
};

[[noreturn]] void jpegOnError(j_common_ptr info) {
  auto* err = reinterpret_cast<ErrorManager*>(info->err);
  (*info->err->format_message)(info, err->message);
  std::longjmp(err->jump, 1);
}

// libjpeg prints warnings (corrupt data, premature end) on stderr by default: chronomap counts
// them instead (num_warnings) and refuses the image.
void onMessage(j_common_ptr info, int level) {
  if (level < 0) ++info->err->num_warnings;
}

/// Says in `error` that the image declares more pixels than its bytes allow (outside decodeJpeg(),
/// as setMessage is).
[[gnu::noinline]] void tooLarge(uint64_t width, uint64_t height, size_t bytes, std::string& error) {
  error = "declares " + std::to_string(width) + " x " + std::to_string(height) + " pixels in " +
          std::to_string(bytes) + " bytes; refusing to decode it";
}

/// Plain data only across setjmp: the buffer belongs to `out`.
bool decodeJpeg(const std::vector<uint8_t>& file, ImageRgb& out, std::string& error) {
  jpeg_decompress_struct info;
  ErrorManager err;
  info.err = jpeg_std_error(&err.base);
  err.base.error_exit = jpegOnError;
  err.base.emit_message = onMessage;
  if (setjmp(err.jump)) {
    jpeg_destroy_decompress(&info);
    setMessage(error, err.message[0] ? err.message : "corrupt JPEG");
    return false;
  }
  jpeg_create_decompress(&info);
  info.mem->max_memory_to_use = 512L << 20;
  jpeg_mem_src(&info, file.data(), static_cast<unsigned long>(file.size()));
  jpeg_read_header(&info, TRUE);
  const uint64_t pixels = uint64_t{info.image_width} * info.image_height;
  const uint64_t allowance = std::max(kMinAllowance, uint64_t{file.size()} * kMaxExpansion);
  if (info.image_width > kMaxImageSide || info.image_height > kMaxImageSide || pixels * 3 > allowance) {
    tooLarge(info.image_width, info.image_height, file.size(), error);
    jpeg_destroy_decompress(&info);
    return false;
  }
  info.out_color_space = JCS_RGB;
  jpeg_start_decompress(&info);
  out.width = info.output_width;
  out.height = info.output_height;
  out.pixels.resize(static_cast<size_t>(pixels));
  static_assert(sizeof(Rgb) == 3, "pixels are written as packed RGB");
  while (info.output_scanline < info.output_height) {
    JSAMPROW row = reinterpret_cast<JSAMPROW>(out.pixels.data() + size_t{info.output_scanline} * out.width);
    jpeg_read_scanlines(&info, &row, 1);
  }
  jpeg_finish_decompress(&info);
  const long warnings = err.base.num_warnings;
  jpeg_destroy_decompress(&info);
  if (warnings > 0) {
    setMessage(error, "corrupt or truncated JPEG data");
    return false;
  }
  return true;
}

}  // namespace

bool looksLikeJpeg(const std::vector<uint8_t>& bytes) {
  return bytes.size() >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF;
}

ImageRgb decodeJpegRgb(const std::vector<uint8_t>& bytes, const std::string& name) {
  if (!looksLikeJpeg(bytes)) throw FormatError(name + ": not a JPEG file (bad signature)");
  ImageRgb image;
  std::string error;
  if (!decodeJpeg(bytes, image, error)) throw FormatError(name + ": " + error);
  return image;
}

std::vector<uint8_t> encodeJpeg(const ImageRgb& image, const JpegEncoding& e) {
  if (e.quality < 1 || e.quality > 100) throw UsageError("JPEG quality must lie in 1..100");
  if (image.width == 0 || image.height == 0 || image.pixels.size() != size_t{image.width} * image.height) {
    throw UsageError("cannot encode an empty or inconsistent image as JPEG");
  }
  jpeg_compress_struct info;
  jpeg_error_mgr err;
  info.err = jpeg_std_error(&err);  // encoding chronomap's own buffer in memory cannot fail
  jpeg_create_compress(&info);
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  jpeg_mem_dest(&info, &buffer, &size);
  info.image_width = image.width;
  info.image_height = image.height;
  info.input_components = e.grey ? 1 : 3;
  info.in_color_space = e.grey ? JCS_GRAYSCALE : JCS_RGB;
  jpeg_set_defaults(&info);
  jpeg_set_quality(&info, e.quality, TRUE);
  if (e.progressive) jpeg_simple_progression(&info);
  jpeg_start_compress(&info, TRUE);
  std::vector<uint8_t> grey(e.grey ? image.width : 0);
  while (info.next_scanline < info.image_height) {
    const Rgb* row = image.pixels.data() + size_t{info.next_scanline} * image.width;
    if (e.grey) {
      for (uint32_t x = 0; x < image.width; ++x) grey[x] = row[x].r;
    }
    // libjpeg reads but does not write the row; its API has no const.
    JSAMPROW samples = e.grey ? grey.data() : const_cast<JSAMPLE*>(reinterpret_cast<const JSAMPLE*>(row));
    jpeg_write_scanlines(&info, &samples, 1);
  }
  jpeg_finish_compress(&info);
  jpeg_destroy_compress(&info);
  std::vector<uint8_t> bytes(buffer, buffer + size);
  std::free(buffer);
  return bytes;
}

ImageRgb readColourImage(const std::filesystem::path& path) {
  const std::vector<uint8_t> bytes = readFileBytes(path);
  if (looksLikeJpeg(bytes)) return decodeJpegRgb(bytes, path.string());
  static constexpr uint8_t kPngSignature[4] = {0x89, 'P', 'N', 'G'};
  if (bytes.size() >= 4 && std::equal(kPngSignature, kPngSignature + 4, bytes.begin())) {
    return decodePngRgb(bytes, path.string());
  }
  throw FormatError(path.string() + ": a colour frame must be PNG or JPEG, and this file is neither");
}

}  // namespace chronomap
