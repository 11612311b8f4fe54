#include "chronomap/ingest/png.h"

#include <png.h>

#include <csetjmp>
#include <cstring>
#include <sstream>
#include <string>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "setjmp_message.h"

namespace chronomap {

namespace {

struct PngContext {
  const uint8_t* data = nullptr;
  size_t size = 0;
  size_t offset = 0;
  char message[256] = {0};
  std::vector<uint8_t>* out = nullptr;
};

void pngOnError(png_structp png, png_const_charp msg) {
  auto* ctx = static_cast<PngContext*>(png_get_error_ptr(png));
  std::snprintf(ctx->message, sizeof(ctx->message), "%s", msg);
  longjmp(png_jmpbuf(png), 1);
}
void onWarning(png_structp, png_const_charp) {}

void readFromMemory(png_structp png, png_bytep dst, png_size_t n) {
  auto* ctx = static_cast<PngContext*>(png_get_io_ptr(png));
  if (ctx->offset + n > ctx->size) png_error(png, "file is truncated");
  std::memcpy(dst, ctx->data + ctx->offset, n);
  ctx->offset += n;
}

void writeToMemory(png_structp png, png_bytep src, png_size_t n) {
  auto* ctx = static_cast<PngContext*>(png_get_io_ptr(png));
  ctx->out->insert(ctx->out->end(), src, src + n);
}
void flushNothing(png_structp) {}

/// Deflate, the compression of PNG's image data, expands at most 1032:1: a match of at most 258
/// bytes costs at least 2 bits (a 1-bit length code and a 1-bit distance code), a literal at
/// least 1 bit for 1 byte. So a file of N bytes cannot hold more than 1032 N bytes of pixels.
constexpr uint64_t kMaxDeflateRatio = 1032;
/// Ancillary chunks chronomap never uses. libpng would decompress text and colour profiles (up to
/// 8 MB each, its default chunk limit, which stays) and keep up to 1000 of them: an 8 MB file of
/// small zTXt bombs could take 8 GB. They are skipped unread instead.
constexpr png_byte kSkippedChunks[] = {'i', 'C', 'C', 'P', 0, 'z', 'T', 'X', 't', 0, 'i', 'T', 'X', 't', 0,
                                       't', 'E', 'X', 't', 0, 's', 'P', 'L', 'T', 0, 'e', 'X', 'I', 'f', 0};

/// Checks, after png_read_info and before anything is allocated, that the image the header
/// declares could be held by the file: its samples (a lower bound of the decompressed data, with
/// or without interlacing) must not exceed what `file_size` bytes of deflate can expand to. Not
/// inlined into decodePng(), whose setjmp frame must hold no string (setjmp_message.h).
[[gnu::noinline]] bool declaredSizeFits(png_structp png, png_infop info, size_t file_size, std::string& error) {
  const uint64_t w = png_get_image_width(png, info), h = png_get_image_height(png, info);
  const uint64_t bits_per_pixel = uint64_t{png_get_bit_depth(png, info)} * png_get_channels(png, info);
  const uint64_t sample_bytes = w * h * bits_per_pixel / 8;  // at most 2^30 * 64 bits: no overflow
  if (sample_bytes <= kMaxDeflateRatio * file_size) return true;
  std::ostringstream msg;
  msg << "declares a " << w << " x " << h << " image (" << sample_bytes << " bytes of samples) but holds only "
      << file_size << " bytes, which cannot expand to more than " << kMaxDeflateRatio * file_size
      << " (a decompression bomb or a damaged header)";
  error = msg.str();
  return false;
}

struct Decoded {
  uint32_t width = 0, height = 0;
  int channels = 0;
  int bit_depth = 0;
  std::vector<uint8_t> bytes;  // rows, native-endian 16-bit samples when bit_depth == 16
  std::vector<png_bytep> rows;  // owned here, not in decodePng(): a longjmp skips destructors
};

/// Says in `error` that the image is not a 16-bit grey depth image (outside decodePng(), as
/// setMessage is).
[[gnu::noinline]] void notADepthImage(int depth, int colour_type, std::string& error) {
  error = "expected a 16-bit single-channel depth image, found " + std::to_string(depth) + "-bit " +
          (colour_type == PNG_COLOR_TYPE_GRAY ? "grey" : "colour");
}

/// Decodes `file` to either RGB8 (want16 = false) or raw grey samples (want16 = true).
/// Only plain data lives in this frame across setjmp (buffers belong to `out`, whose destructor
/// a longjmp cannot skip); errors come back as a message.
bool decodePng(const std::vector<uint8_t>& file, bool want16, Decoded& out, std::string& error) {
  PngContext ctx;
  ctx.data = file.data();
  ctx.size = file.size();
  if (file.size() < 8 || png_sig_cmp(file.data(), 0, 8) != 0) {
    setMessage(error, "not a PNG file (bad signature)");
    return false;
  }
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &ctx, pngOnError, onWarning);
  if (!png) {
    setMessage(error, "cannot allocate PNG decoder");
    return false;
  }
  png_infop info = png_create_info_struct(png);
  if (!info || setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    setMessage(error, ctx.message[0] ? ctx.message : "corrupt PNG");
    return false;
  }
  png_set_user_limits(png, kMaxImageSide, kMaxImageSide);
  png_set_keep_unknown_chunks(png, PNG_HANDLE_CHUNK_NEVER, kSkippedChunks, sizeof(kSkippedChunks) / 5);
  png_set_read_fn(png, &ctx, readFromMemory);
  png_read_info(png, info);
  if (!declaredSizeFits(png, info, file.size(), error)) {
    png_destroy_read_struct(&png, &info, nullptr);
    return false;
  }
  const int colour_type = png_get_color_type(png, info);
  const int depth = png_get_bit_depth(png, info);
  if (want16) {
    if (colour_type != PNG_COLOR_TYPE_GRAY || depth != 16) {
      png_destroy_read_struct(&png, &info, nullptr);
      notADepthImage(depth, colour_type, error);
      return false;
    }
    png_set_swap(png);  // PNG stores 16-bit samples big-endian
  } else {
    if (depth == 16) png_set_strip_16(png);
    if (colour_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (colour_type == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
    if (colour_type == PNG_COLOR_TYPE_GRAY || colour_type == PNG_COLOR_TYPE_GRAY_ALPHA) png_set_gray_to_rgb(png);
    if (colour_type & PNG_COLOR_MASK_ALPHA) png_set_strip_alpha(png);
    if (png_get_valid(png, info, PNG_INFO_tRNS)) png_set_strip_alpha(png);
  }
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  out.width = png_get_image_width(png, info);
  out.height = png_get_image_height(png, info);
  out.channels = png_get_channels(png, info);
  out.bit_depth = png_get_bit_depth(png, info);
  const size_t rowbytes = png_get_rowbytes(png, info);
  if ((want16 && rowbytes != size_t{out.width} * 2) || (!want16 && rowbytes != size_t{out.width} * 3)) {
    png_destroy_read_struct(&png, &info, nullptr);
    setMessage(error, "unsupported PNG layout");
    return false;
  }
  out.bytes.resize(rowbytes * out.height);
  out.rows.resize(out.height);
  for (uint32_t y = 0; y < out.height; ++y) out.rows[y] = out.bytes.data() + y * rowbytes;
  png_read_image(png, out.rows.data());
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  return true;
}

bool encode(uint32_t w, uint32_t h, bool sixteen, const uint8_t* data, std::vector<uint8_t>& out,
            std::string& error) {
  PngContext ctx;
  ctx.out = &out;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &ctx, pngOnError, onWarning);
  if (!png) {
    setMessage(error, "cannot allocate PNG encoder");
    return false;
  }
  png_infop info = png_create_info_struct(png);
  if (!info || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    setMessage(error, ctx.message[0] ? ctx.message : "PNG encoding failed");
    return false;
  }
  png_set_write_fn(png, &ctx, writeToMemory, flushNothing);
  png_set_IHDR(png, info, w, h, sixteen ? 16 : 8, sixteen ? PNG_COLOR_TYPE_GRAY : PNG_COLOR_TYPE_RGB,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_compression_level(png, 3);
  png_write_info(png, info);
  if (sixteen) png_set_swap(png);
  const size_t rowbytes = size_t{w} * (sixteen ? 2 : 3);
  for (uint32_t y = 0; y < h; ++y) png_write_row(png, const_cast<png_bytep>(data + y * rowbytes));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

ImageRgb readPngRgb(const std::filesystem::path& path) {
  return readNamingMemory(path, [&] { return decodePngRgb(readFileBytes(path), path.string()); });
}

ImageU16 readPngU16(const std::filesystem::path& path) {
  return readNamingMemory(path, [&] { return decodePngU16(readFileBytes(path), path.string()); });
}

ImageRgb decodePngRgb(const std::vector<uint8_t>& file, const std::string& name) {
  Decoded d;
  std::string error;
  if (!decodePng(file, false, d, error)) throw FormatError(name + ": " + error);
  ImageRgb img;
  img.width = d.width;
  img.height = d.height;
  img.pixels.resize(size_t{d.width} * d.height);
  std::memcpy(img.pixels.data(), d.bytes.data(), d.bytes.size());
  return img;
}

ImageU16 decodePngU16(const std::vector<uint8_t>& file, const std::string& name) {
  Decoded d;
  std::string error;
  if (!decodePng(file, true, d, error)) throw FormatError(name + ": " + error);
  ImageU16 img;
  img.width = d.width;
  img.height = d.height;
  img.pixels.resize(size_t{d.width} * d.height);
  std::memcpy(img.pixels.data(), d.bytes.data(), d.bytes.size());
  return img;
}

namespace {

template <class Image>
std::vector<uint8_t> encodeImage(const Image& image, bool sixteen, const std::string& name) {
  if (image.pixels.size() != size_t{image.width} * image.height) throw UsageError("writePng: size mismatch");
  std::vector<uint8_t> out;
  std::string error;
  if (!encode(image.width, image.height, sixteen, reinterpret_cast<const uint8_t*>(image.pixels.data()), out, error)) {
    throw IoError(name + ": " + error);
  }
  return out;
}

}  // namespace

std::vector<uint8_t> encodePng(const ImageRgb& image) { return encodeImage(image, false, "PNG"); }

std::vector<uint8_t> encodePng(const ImageU16& image) { return encodeImage(image, true, "PNG"); }

void writePng(const std::filesystem::path& path, const ImageRgb& image) {
  writeFileAtomic(path, encodeImage(image, false, path.string()));
}

void writePng(const std::filesystem::path& path, const ImageU16& image) {
  writeFileAtomic(path, encodeImage(image, true, path.string()));
}

}  // namespace chronomap
