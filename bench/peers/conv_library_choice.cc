// The measurement behind LPIPS's convolution library (docs/lpips.md): AlexNet's second
// convolution at 1 MP input (64 -> 192 channels, 5x5, pad 2, on 143x107 positions, the
// largest layer), run with oneDNN (NHWC, ReLU fused, the way src/rephoto/lpips runs it) and
// with OpenBLAS (im2col + one SGEMM, the way a hand-rolled BLAS convolution would), same
// threads. Prints the median of 7 runs of each, in turns.
//
//   g++ -O3 -std=c++20 bench/peers/conv_library_choice.cc -ldnnl -lopenblas -fopenmp \
//     -o /tmp/conv_choice && OMP_NUM_THREADS=2 OPENBLAS_NUM_THREADS=2 /tmp/conv_choice
#include <cblas.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <oneapi/dnnl/dnnl.hpp>
#include <random>
#include <vector>

int main() {
  const int cin = 64, cout = 192, k = 5, pad = 2, h = 107, w = 143;
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<float> src(size_t(h) * w * cin), wts(size_t(cout) * cin * k * k), bias(cout);
  for (float& v : src) v = u(rng);
  for (float& v : wts) v = u(rng) * 0.05f;
  for (float& v : bias) v = u(rng);
  dnnl::set_max_cpu_isa(dnnl::cpu_isa::avx2);
  using tag = dnnl::memory::format_tag;
  using dt = dnnl::memory::data_type;
  dnnl::engine eng(dnnl::engine::kind::cpu, 0);
  dnnl::stream s(eng);
  dnnl::memory::desc src_md({1, cin, h, w}, dt::f32, tag::nhwc), dst_md({1, cout, h, w}, dt::f32, tag::nhwc);
  dnnl::memory::desc w_any({cout, cin, k, k}, dt::f32, tag::any), b_md({cout}, dt::f32, tag::x);
  dnnl::convolution_forward::desc d(dnnl::prop_kind::forward_inference, dnnl::algorithm::convolution_direct,
                                    src_md, w_any, b_md, dst_md, {1, 1}, {pad, pad}, {pad, pad});
  dnnl::post_ops po;
  po.append_eltwise(1.f, dnnl::algorithm::eltwise_relu, 0.f, 0.f);
  dnnl::primitive_attr attr;
  attr.set_post_ops(po);
  dnnl::convolution_forward::primitive_desc pd(d, attr, eng);
  dnnl::memory user_w({{cout, cin, k, k}, dt::f32, tag::oihw}, eng, wts.data());
  dnnl::memory wm(pd.weights_desc(), eng);
  dnnl::reorder(user_w, wm).execute(s, user_w, wm);
  dnnl::memory sm(src_md, eng, src.data()), bm(b_md, eng, bias.data()), dm(dst_md, eng);
  dnnl::convolution_forward conv(pd);
  std::vector<float> col(size_t(h) * w * cin * k * k), out(size_t(h) * w * cout), wt(size_t(cout) * k * k * cin);
  // Weights as [cout][ky][kx][cin] to match the im2col rows.
  for (int o = 0; o < cout; ++o)
    for (int c = 0; c < cin; ++c)
      for (int y = 0; y < k; ++y)
        for (int x = 0; x < k; ++x) wt[((size_t(o) * k + y) * k + x) * cin + c] = wts[((size_t(o) * cin + c) * k + y) * k + x];
  auto onednn = [&] { conv.execute(s, {{DNNL_ARG_SRC, sm}, {DNNL_ARG_WEIGHTS, wm}, {DNNL_ARG_BIAS, bm}, {DNNL_ARG_DST, dm}}); s.wait(); };
  auto blas = [&] {
#pragma omp parallel for
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        float* row = col.data() + (size_t(y) * w + x) * k * k * cin;
        for (int ky = 0; ky < k; ++ky)
          for (int kx = 0; kx < k; ++kx) {
            const int sy = y + ky - pad, sx = x + kx - pad;
            float* dst = row + (ky * k + kx) * cin;
            if (sy < 0 || sy >= h || sx < 0 || sx >= w) std::fill(dst, dst + cin, 0.f);
            else std::copy_n(src.data() + (size_t(sy) * w + sx) * cin, cin, dst);
          }
      }
    // out[pos][cout] = col[pos][K] * wt[cout][K]^T
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, h * w, cout, k * k * cin, 1.f, col.data(), k * k * cin,
                wt.data(), k * k * cin, 0.f, out.data(), cout);
#pragma omp parallel for
    for (int p = 0; p < h * w; ++p)
      for (int o = 0; o < cout; ++o) out[size_t(p) * cout + o] = std::max(0.f, out[size_t(p) * cout + o] + bias[o]);
  };
  auto time = [](auto&& f) {
    auto t0 = std::chrono::steady_clock::now();
    f();
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  };
  onednn();
  blas();
  std::vector<double> a, b;
  for (int i = 0; i < 7; ++i) {
    a.push_back(time(onednn));
    b.push_back(time(blas));
  }
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  const float* d1 = static_cast<float*>(dm.get_data_handle());
  double diff = 0;
  for (size_t i = 0; i < out.size(); ++i) diff = std::max(diff, double(std::abs(d1[i] - out[i])));
  std::printf("oneDNN %.1f ms, OpenBLAS im2col+sgemm %.1f ms (median of 7), max |diff| %.2g\n", a[3], b[3], diff);
}
