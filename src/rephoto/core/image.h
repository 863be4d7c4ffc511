// The one owning image type.
//
// Layout: interleaved (RGBRGB...), row-major, rows top to bottom, no padding:
// value (x, y, c) is at data()[(y * width + x) * channels + c].
// Pixel (0,0) is the top-left pixel; its area spans [0,1)x[0,1), its centre is (0.5, 0.5).
// Image (float) holds values as stored in the files, scaled to [0,1] (8-bit: v/255,
// 16-bit: v/65535), display-referred, never linearized. EXR/PFM values are kept as they are.
// Mask (uint8) holds 0 = invalid, anything else = valid.
//
// Thread safety: plain value types without synchronization: any number of threads may read an image
// at once, and threads may write disjoint pixels of one image; resizing or moving it needs
// exclusive access.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

namespace rephoto {

// std::allocator whose value-less construct() default-initializes: vector::resize() of
// arithmetic types then leaves new elements unwritten instead of zeroing them (the first
// touch of tens of MB is costly; every writer of an image fills all of it anyway).
template <typename T>
struct DefaultInitAllocator : std::allocator<T> {
  template <typename U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  DefaultInitAllocator() = default;
  template <typename U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}
  template <typename U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

// A vector whose resize() does not zero new elements.
template <typename T>
using UninitVector = std::vector<T, DefaultInitAllocator<T>>;

template <typename T>
class ImageT {
 public:
  using value_type = T;

  ImageT() = default;
  ImageT(int width, int height, int channels, T fill = T(0))
      : width_(width),
        height_(height),
        channels_(channels),
        values_(static_cast<size_t>(width) * height * channels, fill) {}

  int width() const { return width_; }
  int height() const { return height_; }
  int channels() const { return channels_; }
  size_t pixel_count() const { return static_cast<size_t>(width_) * height_; }
  size_t size() const { return values_.size(); }
  bool empty() const { return values_.empty(); }

  T* data() { return values_.data(); }
  const T* data() const { return values_.data(); }
  T* row(int y) { return values_.data() + static_cast<size_t>(y) * width_ * channels_; }
  const T* row(int y) const { return values_.data() + static_cast<size_t>(y) * width_ * channels_; }
  T& at(int x, int y, int c = 0) {
    return values_[(static_cast<size_t>(y) * width_ + x) * channels_ + c];
  }
  T at(int x, int y, int c = 0) const {
    return values_[(static_cast<size_t>(y) * width_ + x) * channels_ + c];
  }

  template <typename U>
  bool SameSize(const ImageT<U>& other) const {
    return width_ == other.width() && height_ == other.height();
  }

  // Reshapes without keeping values: the values are unspecified (not zeroed) until written.
  // Reuses the allocation when it is large enough (first touch of new pages is expensive on
  // the target machines).
  void Resize(int width, int height, int channels) {
    width_ = width;
    height_ = height;
    channels_ = channels;
    values_.resize(static_cast<size_t>(width) * height * channels);
  }

 private:
  int width_ = 0;
  int height_ = 0;
  int channels_ = 0;
  UninitVector<T> values_;
};

using Image = ImageT<float>;
using Mask = ImageT<uint8_t>;
using Image8 = ImageT<uint8_t>;  // 8-bit samples as stored in a file (v stands for v / 255)

}  // namespace rephoto
