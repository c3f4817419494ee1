// render/radiance_cache.h: probes of Eq. 1 and their irradiance for the control variate.
#include "render/radiance_cache.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <optional>
#include <utility>

#include "autodiff/gemm_kernel.h"
#include "autodiff/matmul.h"
#include "render/disney_brdf.h"
#include "render/equirect.h"
#include "render/radiance_query.h"
#include "render/sampling.h"
#include "util/math.h"
#include "util/parallel.h"

namespace sl::render::insertion {

namespace {

// Stores `value` in a shared slot unless it already holds it. Parallel loops mark slots this way:
// every writer stores the same value, so the result does not depend on the order or the thread
// count, and a slot already marked is only read, so the threads share its line instead of taking
// it from each other.
template <class T>
void mark(T& slot, T value) {
  std::atomic_ref<T> ref(slot);
  if (ref.load(std::memory_order_relaxed) != value) ref.store(value, std::memory_order_relaxed);
}

}  // namespace

RadianceCache::RadianceCache(const InsertionInputs& in, const InsertionOptions& opt, const EnvironmentMap& env_map,
              const glm::vec3& lo, const glm::vec3& hi, int max_xz, int max_y, double exact_sky,
              const std::vector<glm::vec3>* occupied, const RayMarcher* marcher)
    : env_map_(env_map), H_(opt.cache_height), W_(opt.cache_width) {
  if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z)) return;  // no rays read it
  if (exact_sky > 0) {
    exact_sky_ = float(exact_sky);
    if (!marcher) own_marcher_ = std::make_unique<const RayMarcher>(in.vsg, in.env, in.grid, opt.query);
    marcher_ = marcher ? marcher : own_marcher_.get();
  }
  lo_ = lo;
  for (int a = 0; a < 3; ++a) {
    const float ext = std::max(0.0f, hi[a] - lo[a]);
    n_[a] = std::clamp(int(std::ceil(ext / opt.cache_spacing_m)) + 1, 2, a == 1 ? max_y : max_xz);
    step_[a] = ext > 0 ? ext / float(n_[a] - 1) : 1.0f;
  }
  const int64_t dense = int64_t(n_[0]) * n_[1] * n_[2];
  if (occupied) {  // only the corners of cells that hold an origin
    slot_.assign(size_t(dense), -1);
    // In parallel: every mark stores 0, so the marks do not depend on the order (a mark already
    // made is not stored again, so the threads share the marked lines).
    parallel_for(int64_t(occupied->size()), 1024, [&](int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i) {
        int64_t probe[8];
        float w[8];
        dense_weights(&(*occupied)[size_t(i)][0], probe, w);
        for (int c = 0; c < 8; ++c) mark(slot_[size_t(probe[c])], int64_t{0});
      }
    });
    for (int64_t j = 0; j < dense; ++j)
      if (slot_[size_t(j)] == 0) {
        slot_[size_t(j)] = int64_t(dense_of_.size());
        dense_of_.push_back(j);
      }
  } else {
    for (int64_t j = 0; j < dense; ++j) dense_of_.push_back(j);
  }
  const int64_t D = int64_t(H_) * W_, P = int64_t(dense_of_.size());
  if (P == 0) return;
  std::vector<glm::vec3> dirs(static_cast<size_t>(D)), sky(static_cast<size_t>(D));
  for (int64_t t = 0; t < D; ++t) {
    const equirect::Dir e = equirect::uv_to_direction(double(t % W_) + 0.5, double(t / W_) + 0.5, W_, H_);
    dirs[size_t(t)] = glm::vec3(float(e.x), float(e.y), float(e.z));
    sky[size_t(t)] = env_map_.lookup(dirs[size_t(t)]);
  }
  // Every probe × direction marched by RayMarcher: radiance_query's forward bit for bit
  // (RayMarcher.EqualsTheQueryBitForBit), without the op's tensors and its planar volume reads.
  std::optional<RayMarcher> own;
  if (!marcher_ && !marcher) own.emplace(in.vsg, in.env, in.grid, opt.query);
  const RayMarcher& probe_marcher = marcher_ ? *marcher_ : marcher ? *marcher : *own;
  cache_.resize(size_t(4 * P * D));
  // Dynamic: a march's length depends on the volume along its direction.
  parallel_for_dynamic(P * D, 64, [&](int64_t b, int64_t e) {
    std::vector<float> xs(size_t(3 * (e - b))), ls(size_t(3 * (e - b)));
    std::vector<RayMarcher::Result> marched(static_cast<size_t>(e - b));
    for (int64_t i = b; i < e; ++i) {
      const glm::vec3 x = probe(dense_of_[size_t(i / D)]), l = dirs[size_t(i % D)];
      for (int c = 0; c < 3; ++c) {
        xs[size_t(3 * (i - b) + c)] = x[c];
        ls[size_t(3 * (i - b) + c)] = l[c];
      }
    }
    probe_marcher(e - b, xs.data(), ls.data(), marched.data());  // in lanes: the same bits
    for (int64_t i = b; i < e; ++i) {
      const RayMarcher::Result& r = marched[size_t(i - b)];
      const glm::vec3& L_env = sky[size_t(i % D)];
      for (int c = 0; c < 3; ++c) cache_[size_t(4 * i + c)] = r.radiance[c] - r.transmittance * L_env[c];
      cache_[size_t(4 * i + 3)] = r.transmittance;
    }
  });
}

// E(probe, normal) = Σ_q max(0, n·d_q) ΔΩ_q L_probe(d_q), L_env bilinear as every ray reads it
// and V, τ as radiance() reads them: one [touched normals × q] × [q × 3·probes] GEMM. The
// quadrature rows are half the env's (a sun over a texel or two is integrated to ~0.3%, where
// texel centres alone miss it by 5%: tests/render/radiance_cache_test.cpp), its texels square.
void RadianceCache::build_irradiance(int hn, int supersample, const std::vector<glm::vec3>& normals,
                                     const std::vector<glm::vec3>* origins) {
  if (cache_.empty()) return;
  SL_CHECK(!(exact_sky_ > 0.0f), "RadianceCache: build_irradiance() integrates the probes; exact directions would differ");
  hn_ = std::max(2, hn);
  wn_ = 2 * hn_;
  const int ss = std::max(1, supersample);
  const int hq = ss * std::max(2 * env_map_.height(), H_);
  const int wq = std::max({2 * hq, ss * env_map_.width(), ss * W_});
  const int64_t Q = int64_t(hq) * wq, P = probes(), D = int64_t(H_) * W_;
  node_row_.assign(size_t(hn_) * wn_, -1);
  SL_CHECK(int64_t(hn_) * wn_ <= INT32_MAX, "RadianceCache: normal grid ", wn_, "x", hn_, " is too large");
  // Each normal's taps once (its panorama coordinates a batch per chunk: the bits irradiance()
  // reads them with), in parallel; they mark the touched nodes here and the (node, probe) pairs
  // in needed_pairs(). Every mark stores the same value, so the marks do not depend on the order
  // or the thread count (a mark already made is not stored again: the threads then share the
  // marked lines instead of taking them from each other).
  std::vector<NormalTaps> ntaps(normals.size());
  parallel_for(int64_t(normals.size()), 1024, [&](int64_t b, int64_t e) {
    std::vector<equirect::UV> units(size_t(e - b));
    equirect::directions_to_units(int(e - b), &normals[size_t(b)], units.data());
    for (int64_t i = b; i < e; ++i) {
      const glm::vec3& n = normals[size_t(i)];
      NormalTaps& nt = ntaps[size_t(i)];
      nt.valid = all_finite(n) && glm::dot(n, n) > 0.0f;
      nt.nonzero = 0;
      if (!nt.valid) continue;
      const EnvTaps taps = env_bilinear_taps_unit(units[size_t(i - b)], wn_, hn_);
      for (int k = 0; k < 4; ++k) {
        nt.index[k] = int32_t(taps.index[k]);
        if (taps.weight[k] != 0.0) nt.nonzero |= uint8_t(1u << k);
        mark(node_row_[size_t(taps.index[k])], int64_t{0});
      }
    }
  });
  // Rows in tiles of the normal grid (kTile × kTile nodes, tile by tile): a block of kBlock rows
  // then holds normals of a narrow cone, and the quadrature directions below every one of their
  // hemispheres drop out of its GEMM (see below). A row's E does not depend on its block.
  constexpr int kTile = 8;
  std::vector<int64_t> nodes;
  for (int ty = 0; ty < hn_; ty += kTile)
    for (int tx = 0; tx < wn_; tx += kTile)
      for (int y = ty; y < std::min(hn_, ty + kTile); ++y)
        for (int x = tx; x < std::min(wn_, tx + kTile); ++x) {
          const size_t j = size_t(y) * size_t(wn_) + size_t(x);
          if (node_row_[j] != 0) continue;
          node_row_[j] = int64_t(nodes.size());
          nodes.push_back(int64_t(j));
        }
  const int64_t Nn = int64_t(nodes.size());
  if (Nn == 0) return;
  std::vector<glm::vec3> qdir(static_cast<size_t>(Q));
  std::vector<float> lq(size_t(Q * 3 * P));  // [q][probe][rgb] · ΔΩ_q
  parallel_for(Q, 64, [&](int64_t b, int64_t e) {
    for (int64_t q = b; q < e; ++q) {
      // The row's direction sits at its solid-angle centroid in elevation, not its middle: the
      // quadrature is then exact for radiance linear in elevation across the row (the bilinear
      // sky between its rows), where the middle errs by the cos(θ) weight's tilt, most near the
      // zenith. KITTI 000008 under release 0.6.0 (a sun 6° from the zenith), the object's
      // bias 0.83% → 0.55% (streetlight-bench insert --bias-runs 16, row bias_no_filters).
      const int row = int(q / wq);
      const double t0 = (0.5 - double(row) / hq) * kPi, t1 = (0.5 - double(row + 1) / hq) * kPi;
      const double el = ((t0 * std::sin(t0) + std::cos(t0)) - (t1 * std::sin(t1) + std::cos(t1))) /
                        (std::sin(t0) - std::sin(t1));
      const equirect::Dir d = equirect::uv_to_direction(double(q % wq) + 0.5, (0.5 - el / kPi) * hq, wq, hq);
      const glm::vec3 l(float(d.x), float(d.y), float(d.z));
      qdir[size_t(q)] = l;
      const equirect::UV unit = equirect::direction_to_uv(l.x, l.y, l.z, 1, 1);
      const EnvTaps taps = env_bilinear_taps_unit(unit, W_, H_);
      const glm::vec3 sky = env_map_.lookup_unit(unit);
      const float solid = float(equirect::pixel_solid_angle(int(q / wq), wq, hq));
      for (int64_t p = 0; p < P; ++p) {
        glm::vec4 acc(0.0f);
        for (int k = 0; k < 4; ++k) {
          const float* c = &cache_[size_t(4 * (p * D + taps.index[k]))];
          acc += float(taps.weight[k]) * glm::vec4(c[0], c[1], c[2], c[3]);
        }
        const glm::vec3 L = (glm::vec3(acc) + acc.w * sky) * solid;
        for (int c = 0; c < 3; ++c) lq[size_t((q * P + p) * 3 + c)] = L[c];
      }
    }
  });
  // Blocks of 32 normals (the last takes the rest, up to 63; 128 without the packed kernel), one
  // per thread at a time: rows [kernel][normal of the block][q] = max(0, n·d_q), then
  // max(0, n·d_q)·(1 − max(0, n·d_q))^5, and one GEMM for both kernels (the
  // kernel matrix of all touched normals at once was 125 MB of fresh pages on KITTI 000008).
  // Only the columns q that some normal of the block faces enter the GEMM: each element of C is
  // one FMA sequence over q in order (autodiff/gemm_kernel.h), and a column of zeros adds
  // fma(0, b, acc) = acc to it, so dropping those columns keeps every bit as long as lq is
  // finite (checked: otherwise every column stays). KITTI 000008: 5369 normals, 50 probes,
  // 8192 directions; the GEMM was 8% of the insertion's CPU time (perf, 1 thread). Blocks of 32
  // rather than 128 normals face fewer directions (64% of them on average -> 56%) and read fewer
  // probes (below); no block is shorter than 32 rows, so every call stays on the packed path.
  // Without the packed kernel (a scalar build) the blocks stay those of 128 normals and every
  // probe stays: Eigen's blocking depends on the product's shape, so this keeps its bits too.
  const bool packed_kernel = detail::gemm_kernel_available();
  const int64_t kBlock = packed_kernel ? 32 : 128;
  touched_ = Nn;
  irradiance_.assign(size_t(2 * Nn * 3 * P), 0.0f);
  const int64_t blocks = packed_kernel ? std::max<int64_t>(1, Nn / kBlock) : (Nn + kBlock - 1) / kBlock;
  const bool finite = std::all_of(lq.begin(), lq.end(), [](float v) { return std::isfinite(v); });
  const std::vector<uint8_t> needed = origins ? needed_pairs(ntaps, *origins) : std::vector<uint8_t>{};
  // The quadrature directions axis by axis, so that the loop over them below runs in vector lanes.
  std::vector<float> qx(static_cast<size_t>(Q)), qy(static_cast<size_t>(Q)), qz(static_cast<size_t>(Q));
  for (int64_t q = 0; q < Q; ++q) {
    qx[size_t(q)] = qdir[size_t(q)].x;
    qy[size_t(q)] = qdir[size_t(q)].y;
    qz[size_t(q)] = qdir[size_t(q)].z;
  }
  // Dynamic: the blocks' costs differ (the probes and directions they read), and a static split
  // left one thread waiting about 10 ms (perf, KITTI 000008). The scratch is the thread's, so a
  // chunk of one block does not allocate 2 MB anew; each block writes every row it reads first.
  parallel_for_dynamic(blocks, 1, [&](int64_t bb, int64_t be) {
    static thread_local std::vector<float> cosines, a, b;
    static thread_local std::vector<uint8_t> faced;
    static thread_local std::vector<int64_t> cols, used;
    static thread_local std::vector<std::array<int64_t, 3>> runs;
    static thread_local std::vector<std::pair<int64_t, int64_t>> col_runs;
    cosines.resize(size_t(2 * kBlock * Q));
    faced.resize(static_cast<size_t>(Q));
    for (int64_t blk = bb; blk < be; ++blk) {
      const int64_t b0 = blk * kBlock, nb = blk + 1 == blocks ? Nn - b0 : kBlock;  // the last: the rest
      // The probes some (origin, normal) pair reads with a normal node of this block.
      used.clear();
      for (int64_t p = 0; p < P; ++p) {
        bool any = needed.empty();
        for (int64_t i = 0; i < nb && !any; ++i) any = needed[size_t((b0 + i) * P + p)] != 0;
        if (any) used.push_back(p);
      }
      if (used.empty()) continue;  // no read meets the block: its E stays 0, never read
      std::fill(faced.begin(), faced.end(), uint8_t(0));
      // In vector lanes: local pointers, and one comparison for both outputs (std::max and a second
      // test of its result kept the loop scalar; through the thread_local vectors it reloaded them
      // on every store): half the irradiance's own time under perf, Intel Xeon. glm::dot as
      // before, so the same contractions (a hand-written n.x·d.x + … fuses other products).
      const float* const dx = qx.data();
      const float* const dy = qy.data();
      const float* const dz = qz.data();
      uint8_t* const face = faced.data();
      const int64_t nq = Q;
      for (int64_t i = 0; i < nb; ++i) {
        const int64_t j = nodes[size_t(b0 + i)];
        const equirect::Dir d = equirect::uv_to_direction(double(j % wn_) + 0.5, double(j / wn_) + 0.5, wn_, hn_);
        const glm::vec3 n(float(d.x), float(d.y), float(d.z));
        float* const a1 = &cosines[size_t(i * Q)];
        for (int64_t q = 0; q < nq; ++q) {
          const float dot = glm::dot(n, glm::vec3(dx[q], dy[q], dz[q]));
          const bool front = 0.0f < dot;
          a1[q] = front ? dot : 0.0f;  // std::max(0.0f, dot)
          face[q] |= uint8_t(front);
        }
      }
      cols.clear();
      for (int64_t q = 0; q < Q; ++q)
        if (faced[size_t(q)] || !finite) cols.push_back(q);
      // The packed kernel serves both calls (matmul.cpp, use_packed) unless K is tiny; there
      // every column stays, so the call is the one it always was. Without the packed kernel
      // every column stays too: Eigen's blocking depends on K.
      if (!packed_kernel || int64_t(cols.size()) < 16 || 2 * nb * 3 * P * int64_t(cols.size()) < (int64_t{1} << 18)) {
        cols.resize(size_t(Q));
        for (int64_t q = 0; q < Q; ++q) cols[size_t(q)] = q;
      }
      const int64_t Kq = int64_t(cols.size());
      a.resize(size_t(2 * nb * Kq));
      b.resize(size_t(Kq * 3 * P));
      // The kept columns as runs {first q, count}: a hemisphere's directions are a few long runs,
      // so the rows below are contiguous copies and lane loops rather than indexed loads.
      col_runs.clear();
      for (int64_t k = 0; k < Kq; ++k) {
        if (k > 0 && cols[size_t(k)] == cols[size_t(k - 1)] + 1) ++col_runs.back().second;
        else col_runs.push_back({cols[size_t(k)], 1});
      }
      for (int64_t i = 0; i < nb; ++i) {
        const float* const a1 = &cosines[size_t(i * Q)];
        float* r1 = &a[size_t(i * Kq)];
        float* r5 = &a[size_t((nb + i) * Kq)];
        for (const auto& [q0, count] : col_runs) {
          const float* const src = a1 + q0;
          for (int64_t k = 0; k < count; ++k) {
            const float c = src[k];
            r1[k] = c;
            r5[k] = c * disney::schlick_weight(c);
          }
          r1 += count;
          r5 += count;
        }
      }
      // Only the probes of `used` enter the GEMM (B's columns): the packed kernel computes each
      // element of C alone, whatever the panel (autodiff/gemm_kernel.h), so the E it returns keep
      // their bits as long as both the whole call and the narrower one take the packed path
      // (matmul.cpp, use_packed: M >= kBlockRows, K >= 16, M·N·K >= 2^18); otherwise every
      // probe stays. KITTI 000008: a block of 32 normals reads 20 of the 50 probes on average;
      // with the blocks of 32, the irradiance took 129 ms instead of 195 (1 thread, the GEMM
      // 110 -> 43 ms; streetlight-bench insert --size kitti --rows production).
      auto packed = [&](int64_t n_cols) {
        return packed_kernel && 2 * nb >= detail::kBlockRows && Kq >= 16 &&
               2 * nb * n_cols * Kq >= (int64_t{1} << 18);
      };
      if (int64_t(used.size()) < P && !(packed(3 * P) && packed(3 * int64_t(used.size())))) {
        used.resize(size_t(P));
        for (int64_t p = 0; p < P; ++p) used[size_t(p)] = p;
      }
      const int64_t Pu = int64_t(used.size());
      runs.clear();  // {first probe, count, column in B} of consecutive used probes
      for (int64_t u = 0; u < Pu; ++u) {
        if (u > 0 && used[size_t(u)] == used[size_t(u - 1)] + 1) ++runs.back()[1];
        else runs.push_back({used[size_t(u)], 1, u});
      }
      b.resize(size_t(Kq * 3 * Pu));
      for (int64_t k = 0; k < Kq; ++k) {
        const float* src = &lq[size_t(cols[size_t(k)] * 3 * P)];
        float* dst = &b[size_t(k * 3 * Pu)];
        for (const auto& r : runs) std::copy_n(src + 3 * r[0], 3 * r[1], dst + 3 * r[2]);
      }
      // One block, both kernels: rows [0, nb) and [nb, 2·nb) of `a` (the GEMM runs on this thread:
      // nested in the loop over blocks).
      std::vector<float> e(size_t(2 * nb * 3 * Pu));
      detail::gemm<float>(false, false, 2 * nb, 3 * Pu, Kq, 1.0f, a.data(), Kq, b.data(), 3 * Pu, 0.0f, e.data(), 3 * Pu);
      for (int64_t r = 0; r < 2 * nb; ++r) {
        const int64_t row = r < nb ? b0 + r : Nn + b0 + (r - nb);
        for (int64_t u = 0; u < Pu; ++u)
          std::copy_n(&e[size_t((r * Pu + u) * 3)], 3, &irradiance_[size_t((row * P + used[size_t(u)]) * 3)]);
      }
    }
  });
}

// Per (normal node row, probe): 1 where irradiance(corners(origins[i]), normals[i]) reads it
// with a non-zero weight, the reads of shade_foreground().
std::vector<uint8_t> RadianceCache::needed_pairs(const std::vector<NormalTaps>& taps,
                                                 const std::vector<glm::vec3>& origins) const {
  SL_CHECK(origins.size() == taps.size(), "RadianceCache: ", origins.size(), " origins for ", taps.size(),
           " normals");
  const int64_t P = probes();
  std::vector<uint8_t> needed(size_t(touched_ * P), 0);
  // In parallel: every mark stores 1, so the result does not depend on the order (and a mark
  // already made is not stored again, as in build_irradiance()).
  parallel_for(int64_t(taps.size()), 1024, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      const NormalTaps& nt = taps[size_t(i)];
      if (!nt.valid) continue;
      const Corners at = corners(&origins[size_t(i)][0]);
      for (int k = 0; k < 4; ++k) {
        const int64_t row = node_row_[size_t(nt.index[k])];
        if (row < 0 || !(nt.nonzero & (1u << k))) continue;
        for (int c = 0; c < 8; ++c)
          if (at.weight[c] != 0.0f) mark(needed[size_t(row * P + at.probe[c])], uint8_t{1});
      }
    }
  });
  return needed;
}

// E(x, n) of build_irradiance() (n among the normals it was given): trilinear in the probes,
// bilinear in the normal.
RadianceCache::Irradiance RadianceCache::irradiance(const glm::vec3& origin, const glm::vec3& n) const {
  return irradiance(corners(&origin[0]), n);
}

RadianceCache::Irradiance RadianceCache::irradiance(const Corners& at, const glm::vec3& n) const {
  Irradiance out;
  if (irradiance_.empty() || !all_finite(n) || !(glm::dot(n, n) > 0.0f)) return out;
  const int64_t* probe = at.probe;
  const float* wp = at.weight;
  const EnvTaps taps = env_bilinear_taps_unit(equirect::direction_to_unit(n.x, n.y, n.z), wn_, hn_);  // as marked
  const int64_t P = probes();
  for (int k = 0; k < 4; ++k) {
    const int64_t row = node_row_[size_t(taps.index[k])];
    if (row < 0 || taps.weight[k] == 0.0) continue;
    for (int c = 0; c < 8; ++c) {
      if (wp[c] == 0.0f) continue;
      const float w = wp[c] * float(taps.weight[k]);
      const float* e1 = &irradiance_[size_t((row * P + probe[c]) * 3)];
      const float* e5 = &irradiance_[size_t(((touched_ + row) * P + probe[c]) * 3)];
      out.cosine += w * glm::vec3(e1[0], e1[1], e1[2]);
      out.grazing += w * glm::vec3(e5[0], e5[1], e5[2]);
    }
  }
  return out;
}

glm::vec3 RadianceCache::radiance(const float* origin, const float* dir) const {
  const glm::vec3 l(dir[0], dir[1], dir[2]);
  if (!(glm::dot(l, l) > 0.0f) || !all_finite(l)) return glm::vec3(0.0f);
  return radiance_unit(origin, equirect::direction_to_unit(l.x, l.y, l.z));  // one conversion for both maps
}

RadianceCache::Corners RadianceCache::corners(const float* origin) const {
  Corners at;
  probe_weights(origin, at.probe, at.weight);
  at.origin = glm::vec3(origin[0], origin[1], origin[2]);
  return at;
}

glm::vec3 RadianceCache::radiance_unit(const float* origin, const equirect::UV& unit) const {
  if (cache_.empty()) return glm::vec3(0.0f);
  return radiance_unit(corners(origin), unit);
}

glm::vec3 RadianceCache::radiance_unit(const Corners& at, const equirect::UV& unit) const {
  if (cache_.empty()) return glm::vec3(0.0f);
  const glm::vec3 sky = env_map_.lookup_unit(unit);
  if (exact_direction(sky)) {
    const equirect::Dir d = equirect::uv_to_direction(unit.u, unit.v, 1, 1);
    const float dir[3] = {float(d.x), float(d.y), float(d.z)};
    exact_rays_.fetch_add(1, std::memory_order_relaxed);
    return (*marcher_)(&at.origin[0], dir).radiance;
  }
  return cached(at, unit, sky);
}

void RadianceCache::radiance_units(const Corners& at, const equirect::UV* units, int n, glm::vec3* out) const {
  if (cache_.empty()) {
    std::fill(out, out + n, glm::vec3(0.0f));
    return;
  }
  thread_local std::vector<int> exact;
  thread_local std::vector<float> origins, dirs;
  thread_local std::vector<RayMarcher::Result> marched;
  exact.clear();
  dirs.clear();
  for (int i = 0; i < n; ++i) {
    const glm::vec3 sky = env_map_.lookup_unit(units[i]);
    if (!exact_direction(sky)) {
      out[i] = cached(at, units[i], sky);
      continue;
    }
    const equirect::Dir d = equirect::uv_to_direction(units[i].u, units[i].v, 1, 1);
    exact.push_back(i);
    dirs.insert(dirs.end(), {float(d.x), float(d.y), float(d.z)});
  }
  const int m = int(exact.size());
  if (m == 0) return;
  origins.resize(size_t(3 * m));
  for (int j = 0; j < m; ++j)
    for (int c = 0; c < 3; ++c) origins[size_t(3 * j + c)] = at.origin[c];
  marched.resize(size_t(m));
  (*marcher_)(m, origins.data(), dirs.data(), marched.data());
  for (int j = 0; j < m; ++j) out[exact[size_t(j)]] = marched[size_t(j)].radiance;
  exact_rays_.fetch_add(m, std::memory_order_relaxed);
}

glm::vec3 RadianceCache::cached(const Corners& at, const equirect::UV& unit, const glm::vec3& sky) const {
  const int64_t* probe = at.probe;
  const float* wp = at.weight;
  const EnvTaps taps = env_bilinear_taps_unit(unit, W_, H_);
  const int64_t D = int64_t(H_) * W_;
  glm::vec4 acc(0.0f);
  for (int c = 0; c < 8; ++c) {
    if (wp[c] == 0.0f) continue;
    const float* base = &cache_[size_t(4 * probe[c] * D)];
    for (int k = 0; k < 4; ++k) {
      const float w = wp[c] * float(taps.weight[k]);
      const float* e = base + 4 * taps.index[k];
      acc += w * glm::vec4(e[0], e[1], e[2], e[3]);
    }
  }
  return glm::vec3(acc) + acc.w * sky;
}

// The 8 built probes around a point and their trilinear weights. On a sparse grid a corner
// that was not built (a cell no origin occupied) drops out and the rest are renormalised (all
// missing: weights 0, the read is 0).
void RadianceCache::probe_weights(const float* origin, int64_t probe[8], float w[8]) const {
  dense_weights(origin, probe, w);
  if (slot_.empty()) return;
  float total = 0.0f;
  bool whole = true;
  for (int c = 0; c < 8; ++c) {
    const int64_t s = slot_[size_t(probe[c])];
    if (s < 0) {
      w[c] = 0.0f;
      whole = false;
    }
    probe[c] = std::max<int64_t>(s, 0);
    total += w[c];
  }
  if (whole) return;  // the dense grid's weights, bit for bit
  for (int c = 0; c < 8; ++c) w[c] = total > 0.0f ? w[c] / total : 0.0f;
}

// The 8 grid nodes around a point (clamped to the grid), dense indices, trilinear weights.
void RadianceCache::dense_weights(const float* origin, int64_t probe[8], float w[8]) const {
  int i0[3];
  float f[3];
  for (int a = 0; a < 3; ++a) {
    const float x = std::clamp((origin[a] - lo_[a]) / step_[a], 0.0f, float(n_[a] - 1));
    i0[a] = std::min(int(x), n_[a] - 2);
    f[a] = x - float(i0[a]);
  }
  for (int c = 0; c < 8; ++c) {
    const int ix = i0[0] + (c & 1), iy = i0[1] + ((c >> 1) & 1), iz = i0[2] + (c >> 2);
    w[c] = ((c & 1) ? f[0] : 1 - f[0]) * (((c >> 1) & 1) ? f[1] : 1 - f[1]) * ((c >> 2) ? f[2] : 1 - f[2]);
    probe[c] = (int64_t(iz) * n_[1] + iy) * n_[0] + ix;
  }
}
glm::vec3 RadianceCache::probe(int64_t p) const {
  const int ix = int(p % n_[0]), iy = int(p / n_[0] % n_[1]), iz = int(p / (int64_t(n_[0]) * n_[1]));
  return lo_ + glm::vec3(float(ix) * step_[0], float(iy) * step_[1], float(iz) * step_[2]);
}

void origin_bounds(const std::vector<glm::vec3>& origins, glm::vec3& lo, glm::vec3& hi) {
  lo = glm::vec3(1e30f);
  hi = glm::vec3(-1e30f);
  for (const glm::vec3& o : origins) {
    lo = glm::min(lo, o);
    hi = glm::max(hi, o);
  }
}

}  // namespace sl::render::insertion
