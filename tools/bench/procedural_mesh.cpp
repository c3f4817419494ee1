// Procedural meshes for the BVH benchmark set; see procedural_mesh.h.
#include "tools/bench/procedural_mesh.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <glm/gtc/quaternion.hpp>

#include "util/error.h"
#include "util/math.h"
#include "util/random.h"

namespace sl::bench {
namespace {

using render::Mesh;
using glm::mat3;
using glm::vec3;

// Appends geometry under a current rigid transform (rotation R, then translation T).
struct Builder {
  Mesh m;
  mat3 R{1.0f};
  vec3 T{0.0f};

  uint32_t vert(vec3 p) {
    m.positions.push_back(R * p + T);
    return static_cast<uint32_t>(m.positions.size() - 1);
  }
  void tri(uint32_t a, uint32_t b, uint32_t c) { m.triangles.push_back({a, b, c}); }
  // Quad a b c d in counter-clockwise order: two triangles.
  void quad(vec3 a, vec3 b, vec3 c, vec3 d) {
    const uint32_t i = vert(a), j = vert(b), k = vert(c), l = vert(d);
    tri(i, j, k), tri(i, k, l);
  }
  // Box with centre c, half extents h, rotated by `rot` about its centre: 8 vertices, 12 triangles.
  void box(vec3 c, vec3 h, const mat3& rot = mat3(1.0f)) {
    uint32_t v[8];
    for (int k = 0; k < 8; ++k)
      v[k] = vert(c + rot * vec3((k & 1) ? h.x : -h.x, (k & 2) ? h.y : -h.y, (k & 4) ? h.z : -h.z));
    static const int f[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (const auto& q : f) tri(v[q[0]], v[q[1]], v[q[2]]), tri(v[q[0]], v[q[2]], v[q[3]]);
  }
  // Box spanning [lo, hi] (axis-aligned in the current frame).
  void slab(vec3 lo, vec3 hi) { box(0.5f * (lo + hi), 0.5f * (hi - lo)); }
  // Cylinder (axis = rot's y column) of radius r and half length hl with `seg` sides and capped
  // ends (fans around a centre vertex): 4·seg triangles.
  void cylinder(vec3 c, const mat3& rot, float r, float hl, int seg) {
    const uint32_t top = vert(c + rot * vec3(0, hl, 0)), bottom = vert(c + rot * vec3(0, -hl, 0));
    const uint32_t first = static_cast<uint32_t>(m.positions.size());
    for (int s = 0; s < seg; ++s) {
      const float a = (2.0f * kPiF) * static_cast<float>(s) / static_cast<float>(seg);
      vert(c + rot * vec3(r * std::cos(a), hl, r * std::sin(a)));
      vert(c + rot * vec3(r * std::cos(a), -hl, r * std::sin(a)));
    }
    for (int s = 0; s < seg; ++s) {
      const uint32_t t0 = first + 2 * s, b0 = t0 + 1, t1 = first + 2 * ((s + 1) % seg), b1 = t1 + 1;
      tri(t0, t1, b1), tri(t0, b1, b0), tri(top, t1, t0), tri(bottom, b0, b1);
    }
  }
  // Tube (hollow cylinder) with outer radius r, inner radius ri: 8·seg triangles.
  void tube(vec3 c, const mat3& rot, float r, float ri, float hl, int seg) {
    const uint32_t first = static_cast<uint32_t>(m.positions.size());
    for (int s = 0; s < seg; ++s) {
      const float a = (2.0f * kPiF) * static_cast<float>(s) / static_cast<float>(seg), ca = std::cos(a), sa = std::sin(a);
      vert(c + rot * vec3(r * ca, hl, r * sa)), vert(c + rot * vec3(r * ca, -hl, r * sa));
      vert(c + rot * vec3(ri * ca, hl, ri * sa)), vert(c + rot * vec3(ri * ca, -hl, ri * sa));
    }
    for (int s = 0; s < seg; ++s) {
      const uint32_t a = first + 4 * s, b = first + 4 * ((s + 1) % seg);  // ot ob it ib
      tri(a, b, b + 1), tri(a, b + 1, a + 1);              // outer wall
      tri(a + 2, a + 3, b + 3), tri(a + 2, b + 3, b + 2);  // inner wall
      tri(a, a + 2, b + 2), tri(a, b + 2, b);              // top ring
      tri(a + 1, b + 1, b + 3), tri(a + 1, b + 3, a + 3);  // bottom ring
    }
  }
};

mat3 random_rotation(Rng& rng) {
  glm::quat q(static_cast<float>(rng.normal()), static_cast<float>(rng.normal()), static_cast<float>(rng.normal()),
              static_cast<float>(rng.normal()));
  const float n = glm::length(q);
  return n > 1e-6f ? glm::mat3_cast(q / n) : mat3(1.0f);
}

// A rotation taking +Y to the x, y or z axis (k = 0, 1, 2).
mat3 axis_rotation(int k) {
  if (k == 0) return mat3(vec3(0, -1, 0), vec3(1, 0, 0), vec3(0, 0, 1));
  if (k == 2) return mat3(vec3(1, 0, 0), vec3(0, 0, -1), vec3(0, 1, 0));
  return mat3(1.0f);
}

float log_uniform(Rng& rng, float lo, float hi) {
  return lo * std::exp(static_cast<float>(rng.uniform()) * std::log(hi / lo));
}

// ---------------------------------------------------------------- noise

// Trilinear value noise in [-1, 1] with a smoothstep fade; lattice values hashed from the seed.
float value_noise(uint64_t seed, vec3 p) {
  const vec3 f = glm::floor(p), t = p - f, s = t * t * (3.0f - 2.0f * t);
  const int64_t x = static_cast<int64_t>(f.x), y = static_cast<int64_t>(f.y), z = static_cast<int64_t>(f.z);
  auto lattice = [&](int64_t i, int64_t j, int64_t k) {
    const uint64_t key = (static_cast<uint64_t>(i) * 73856093u) ^ (static_cast<uint64_t>(j) * 19349663u) ^
                         (static_cast<uint64_t>(k) * 83492791u);
    return 2.0f * uniform01f(seed, 0x6e6f697365ull, key) - 1.0f;
  };
  float c[2][2];
  for (int j = 0; j < 2; ++j)
    for (int k = 0; k < 2; ++k)
      c[j][k] = lattice(x, y + j, z + k) + s.x * (lattice(x + 1, y + j, z + k) - lattice(x, y + j, z + k));
  const float c0 = c[0][0] + s.y * (c[1][0] - c[0][0]), c1 = c[0][1] + s.y * (c[1][1] - c[0][1]);
  return c0 + s.z * (c1 - c0);
}

// Fractal sum of `octaves` of value noise; ridged octaves (1 − 2|n|) above `ridge_from`.
float fbm(uint64_t seed, vec3 p, int octaves, int ridge_from) {
  float sum = 0.0f, amp = 0.5f;
  for (int o = 0; o < octaves; ++o) {
    const float n = value_noise(seed + static_cast<uint64_t>(o), p);
    sum += amp * (o >= ridge_from ? 1.0f - 2.0f * std::abs(n) : n);
    p = 2.03f * p + vec3(17.1f, -3.7f, 9.3f);
    amp *= 0.5f;
  }
  return sum;
}

// ---------------------------------------------------------------- kinds

Mesh machine(int64_t target, uint64_t seed) {
  // Parts average about 150 triangles; the grid has about 1.6 cells per part, in a 4 x 1.5 x 2 m
  // box, and cells are filled in a hashed order, so parts are spread over the whole volume.
  for (double f = std::cbrt(1.6 * std::max<double>(1.0, target / 150.0) / 48.0);; f *= 1.3) {
    const int nx = std::max(1, static_cast<int>(std::lround(4 * f))), ny = std::max(1, static_cast<int>(std::lround(1.5 * f))),
              nz = std::max(1, static_cast<int>(std::lround(2 * f)));
    const float s = 4.0f / static_cast<float>(nx);
    std::vector<int64_t> cells(static_cast<size_t>(nx) * ny * nz);
    std::iota(cells.begin(), cells.end(), 0);
    std::sort(cells.begin(), cells.end(), [&](int64_t a, int64_t b) {
      return hash_counter(seed, 2, static_cast<uint64_t>(a)) < hash_counter(seed, 2, static_cast<uint64_t>(b));
    });
    Builder b;
    const float w = nx * s, d = nz * s;
    b.box(vec3(0.5f * w, -0.05f, 0.5f * d), vec3(0.5f * w + 0.1f, 0.05f, 0.5f * d + 0.1f));  // base plate
    for (int64_t cell : cells) {
      if (static_cast<int64_t>(b.m.triangles.size()) >= target) break;
      Rng rng(seed, 3 + static_cast<uint64_t>(cell));
      const int64_t ix = cell % nx, iy = (cell / nx) % ny, iz = cell / (static_cast<int64_t>(nx) * ny);
      const float scale = log_uniform(rng, 0.028f, 0.28f) * s;  // bounding radius <= sqrt(3)·scale < s/2
      const float room = 0.5f * s - 1.7321f * scale;
      const vec3 c = vec3((ix + 0.5f) * s, (iy + 0.5f) * s, (iz + 0.5f) * s) +
                     room * vec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
      const mat3 rot = rng.uniform() < 0.5 ? axis_rotation(static_cast<int>(rng.randint(3))) : random_rotation(rng);
      const int seg = 8 + static_cast<int>(rng.randint(57));
      const double type = rng.uniform();
      if (type < 0.3) {
        b.box(c, scale * vec3(rng.uniform(0.3, 1), rng.uniform(0.3, 1), rng.uniform(0.3, 1)), rot);
      } else if (type < 0.6) {
        b.cylinder(c, rot, scale * static_cast<float>(rng.uniform(0.3, 1)), scale * static_cast<float>(rng.uniform(0.3, 1)), seg);
      } else if (type < 0.8) {  // flange with a ring of hex bolts
        const float hl = 0.15f * scale;
        b.cylinder(c, rot, scale, hl, seg);
        const int bolts = 4 + static_cast<int>(rng.randint(9));
        for (int k = 0; k < bolts; ++k) {
          const float a = (2.0f * kPiF) * static_cast<float>(k) / static_cast<float>(bolts);
          b.cylinder(c + rot * vec3(0.78f * scale * std::cos(a), hl + 0.1f * scale, 0.78f * scale * std::sin(a)), rot,
                     0.08f * scale, 0.1f * scale, 6);
        }
      } else {
        const float r = scale * static_cast<float>(rng.uniform(0.5, 1));
        b.tube(c, rot, r, r * static_cast<float>(rng.uniform(0.5, 0.9)), scale * static_cast<float>(rng.uniform(0.3, 1)), seg / 2 + 6);
      }
    }
    if (static_cast<int64_t>(b.m.triangles.size()) >= target) return std::move(b.m);
  }
}

// One wall face plane z = z0 (facing -z when `front`) of width w and height floors·fh with
// window openings; windows at columns `cols`, width ww, height wh, sill height sh above each floor.
struct WindowGrid {
  float w, fh, ww, wh, sh;
  int floors, cols;
  float x0(int c) const { return (static_cast<float>(c) + 0.5f) * w / static_cast<float>(cols) - 0.5f * ww; }
};

void wall_face(Builder& b, const WindowGrid& g, float z0) {
  for (int f = 0; f < g.floors; ++f) {
    const float y0 = f * g.fh, ys = y0 + g.sh, yt = ys + g.wh, y1 = y0 + g.fh;
    b.quad(vec3(0, y0, z0), vec3(g.w, y0, z0), vec3(g.w, ys, z0), vec3(0, ys, z0));  // below the windows
    b.quad(vec3(0, yt, z0), vec3(g.w, yt, z0), vec3(g.w, y1, z0), vec3(0, y1, z0));  // above
    float x = 0.0f;
    for (int c = 0; c <= g.cols; ++c) {  // piers between windows
      const float xe = c < g.cols ? g.x0(c) : g.w;
      b.quad(vec3(x, ys, z0), vec3(xe, ys, z0), vec3(xe, yt, z0), vec3(x, yt, z0));
      if (c < g.cols) x = g.x0(c) + g.ww;
    }
  }
}

// A wall of thickness t from z = 0 (outside) to z = t with windows, their reveals, frames,
// mullions, glass, sills and (some) balconies.
void window_wall(Builder& b, Rng& rng, const WindowGrid& g, float t) {
  wall_face(b, g, 0.0f);
  wall_face(b, g, t);
  const float fw = 0.06f;  // frame width
  for (int f = 0; f < g.floors; ++f) {
    const bool balconies = f > 0 && rng.uniform() < 0.4;
    for (int c = 0; c < g.cols; ++c) {
      const float x0 = g.x0(c), x1 = x0 + g.ww, y0 = f * g.fh + g.sh, y1 = y0 + g.wh;
      b.quad(vec3(x0, y0, 0), vec3(x0, y0, t), vec3(x0, y1, t), vec3(x0, y1, 0));  // reveals
      b.quad(vec3(x1, y0, 0), vec3(x1, y1, 0), vec3(x1, y1, t), vec3(x1, y0, t));
      b.quad(vec3(x0, y0, 0), vec3(x1, y0, 0), vec3(x1, y0, t), vec3(x0, y0, t));
      b.quad(vec3(x0, y1, 0), vec3(x0, y1, t), vec3(x1, y1, t), vec3(x1, y1, 0));
      const float zf = 0.55f * t;
      b.slab(vec3(x0, y0, zf - 0.04f), vec3(x0 + fw, y1, zf + 0.04f));  // frame
      b.slab(vec3(x1 - fw, y0, zf - 0.04f), vec3(x1, y1, zf + 0.04f));
      b.slab(vec3(x0 + fw, y0, zf - 0.04f), vec3(x1 - fw, y0 + fw, zf + 0.04f));
      b.slab(vec3(x0 + fw, y1 - fw, zf - 0.04f), vec3(x1 - fw, y1, zf + 0.04f));
      const float xm = 0.5f * (x0 + x1), ym = y0 + 0.62f * g.wh;  // mullion and transom
      b.slab(vec3(xm - 0.02f, y0 + fw, zf - 0.025f), vec3(xm + 0.02f, y1 - fw, zf + 0.025f));
      b.slab(vec3(x0 + fw, ym - 0.02f, zf - 0.025f), vec3(x1 - fw, ym + 0.02f, zf + 0.025f));
      b.quad(vec3(x0 + fw, y0 + fw, zf), vec3(x1 - fw, y0 + fw, zf), vec3(x1 - fw, y1 - fw, zf), vec3(x0 + fw, y1 - fw, zf));
      b.slab(vec3(x0 - 0.05f, y0 - 0.05f, -0.08f), vec3(x1 + 0.05f, y0, 0.0f));  // sill
      if (balconies) {
        const float yb = f * g.fh, bx0 = x0 - 0.3f, bx1 = x1 + 0.3f, depth = 1.0f;
        b.slab(vec3(bx0, yb - 0.12f, -depth), vec3(bx1, yb, 0.0f));
        b.slab(vec3(bx0, yb + 1.0f, -depth), vec3(bx1, yb + 1.04f, -depth + 0.04f));  // hand rail
        const int bars = 10;
        for (int k = 0; k <= bars; ++k) {
          const float x = bx0 + (bx1 - bx0 - 0.02f) * static_cast<float>(k) / bars;
          b.slab(vec3(x, yb, -depth), vec3(x + 0.02f, yb + 1.0f, -depth + 0.02f));
        }
      }
    }
  }
}

Mesh facade(int64_t target, uint64_t seed) {
  Builder b;
  const float street = 16.0f;
  float cursor[2] = {0.0f, 0.0f};
  float block_z = 0.0f, xmax = 0.0f;
  for (uint64_t n = 0; static_cast<int64_t>(b.m.triangles.size()) < target; ++n) {
    Rng rng(seed, 100 + n);
    const int side = static_cast<int>(n & 1);
    WindowGrid g;
    g.fh = 3.2f;
    g.floors = 3 + static_cast<int>(rng.randint(8));
    g.w = static_cast<float>(rng.uniform(8, 24));
    g.cols = std::max(1, static_cast<int>((g.w - 1.0f) / static_cast<float>(rng.uniform(2.2, 3.2))));
    g.ww = static_cast<float>(rng.uniform(1.1, 1.6));
    g.wh = static_cast<float>(rng.uniform(1.4, 1.9));
    g.sh = 0.9f;
    const float depth = static_cast<float>(rng.uniform(9, 15)), t = 0.3f, height = g.floors * g.fh;
    // Building frame: facade along +x from the origin, street side at z = 0, interior at z > 0.
    if (side == 0) {
      b.R = mat3(1.0f), b.T = vec3(cursor[0], 0.0f, block_z + 0.5f * street);
    } else {  // across the street, turned to face it
      b.R = mat3(vec3(-1, 0, 0), vec3(0, 1, 0), vec3(0, 0, -1)), b.T = vec3(cursor[1] + g.w, 0.0f, block_z - 0.5f * street);
    }
    cursor[side] += g.w + static_cast<float>(rng.uniform(0.0, 4.0));
    window_wall(b, rng, g, t);  // street facade
    const mat3 R = b.R;
    const vec3 T = b.T;
    b.R = R * mat3(vec3(-1, 0, 0), vec3(0, 1, 0), vec3(0, 0, -1)), b.T = T + R * vec3(g.w, 0.0f, depth);
    window_wall(b, rng, g, t);  // courtyard facade
    b.R = R, b.T = T;
    b.slab(vec3(0, 0, t), vec3(t, height, depth - t));  // blank side walls
    b.slab(vec3(g.w - t, 0, t), vec3(g.w, height, depth - t));
    for (int f = 1; f <= g.floors; ++f) b.slab(vec3(t, f * g.fh - 0.25f, t), vec3(g.w - t, f * g.fh, depth - t));
    b.slab(vec3(0, height, 0), vec3(g.w, height + 0.6f, 0.25f));  // parapet
    xmax = std::max({xmax, cursor[0], cursor[1]});
    if (cursor[0] > 140.0f && cursor[1] > 140.0f) cursor[0] = cursor[1] = 0.0f, block_z += 2.0f * street + 40.0f;
  }
  b.R = mat3(1.0f), b.T = vec3(0.0f);
  const float z0 = -street - 20.0f, z1 = block_z + street + 20.0f, x0 = -20.0f, x1 = xmax + 20.0f;
  b.quad(vec3(x0, 0, z0), vec3(x0, 0, z1), vec3(x1, 0, z1), vec3(x1, 0, z0));  // ground
  return std::move(b.m);
}

Mesh blob(int64_t target, uint64_t seed) {
  // Cube sphere: 6 faces of n x n cells, 12 n^2 triangles.
  const int n = std::max(1, static_cast<int>(std::ceil(std::sqrt(static_cast<double>(target) / 12.0))));
  Builder b;
  const vec3 axes[6][3] = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}},  {{-1, 0, 0}, {0, 0, 1}, {0, 1, 0}},
                           {{0, 1, 0}, {0, 0, 1}, {1, 0, 0}},  {{0, -1, 0}, {1, 0, 0}, {0, 0, 1}},
                           {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}},  {{0, 0, -1}, {0, 1, 0}, {1, 0, 0}}};
  for (const auto& a : axes) {
    const uint32_t first = static_cast<uint32_t>(b.m.positions.size());
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i) {
        const float u = -1.0f + 2.0f * static_cast<float>(i) / n, v = -1.0f + 2.0f * static_cast<float>(j) / n;
        const vec3 dir = glm::normalize(a[0] + u * a[1] + v * a[2]);
        const vec3 warp(fbm(seed + 50, 1.3f * dir, 3, 9), fbm(seed + 60, 1.3f * dir, 3, 9), fbm(seed + 70, 1.3f * dir, 3, 9));
        const float r = 1.0f + 0.35f * fbm(seed, 1.6f * dir + 0.8f * warp, 9, 3);
        b.m.positions.push_back(2.0f * r * dir);
      }
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const uint32_t p = first + static_cast<uint32_t>(j * (n + 1) + i);
        b.tri(p, p + 1, p + n + 2), b.tri(p, p + n + 2, p + n + 1);
      }
  }
  return std::move(b.m);
}

Mesh foliage(int64_t target, uint64_t seed) {
  Builder b;
  const int64_t leaves = std::max<int64_t>(1, target - 2);
  const int trees = static_cast<int>(std::max<int64_t>(1, (leaves + 49'999) / 50'000));
  const int per_row = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(trees))));
  const int clumps = 80;
  auto crown = [&](int tree) { return vec3(4.5f * (tree % per_row), 5.0f, 4.5f * (tree / per_row)); };
  for (int64_t i = 0; i < leaves; ++i) {
    Rng rng(seed, static_cast<uint64_t>(i));
    const int tree = static_cast<int>(i * trees / leaves);
    Rng clump(seed, 1'000'000'000ull + static_cast<uint64_t>(tree) * clumps + static_cast<uint64_t>(rng.randint(clumps)));
    vec3 cc;  // clump centre, uniform in the crown's ellipsoid (rejection, from the clump's stream)
    do cc = vec3(clump.uniform(-1, 1), clump.uniform(-1, 1), clump.uniform(-1, 1));
    while (glm::dot(cc, cc) > 1.0f);
    const float spread = static_cast<float>(clump.uniform(0.25, 0.6));
    const vec3 p = crown(tree) + vec3(2.6f, 2.2f, 2.6f) * cc +
                   spread * vec3(rng.normal(), rng.normal(), rng.normal());
    const mat3 rot = random_rotation(rng);
    const float len = log_uniform(rng, 0.05f, 0.3f), width = len / log_uniform(rng, 20.0f, 200.0f);
    const vec3 d = rot[1], w = 0.5f * width * rot[0];
    b.tri(b.vert(p), b.vert(p + len * d + w), b.vert(p + len * d - w));
  }
  const float x1 = 4.5f * per_row, z1 = 4.5f * ((trees + per_row - 1) / per_row);
  b.quad(vec3(-4, 0, -4), vec3(-4, 0, z1), vec3(x1, 0, z1), vec3(x1, 0, -4));
  return std::move(b.m);
}

Mesh terrain(int64_t target, uint64_t seed) {
  const int n = std::max(1, static_cast<int>(std::ceil(std::sqrt(static_cast<double>(target) / 2.0))));
  Builder b;
  const float size = 1000.0f;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const float x = size * static_cast<float>(i) / n, z = size * static_cast<float>(j) / n;
      b.m.positions.push_back({x, 150.0f * fbm(seed, vec3(x / 250.0f, 0.37f, z / 250.0f), 10, 2), z});
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const uint32_t p = static_cast<uint32_t>(j * (n + 1) + i);
      b.tri(p, p + n + 1, p + n + 2), b.tri(p, p + n + 2, p + 1);
    }
  return std::move(b.m);
}

}  // namespace

const std::vector<std::string>& procedural_mesh_kinds() {
  static const std::vector<std::string> kinds = {"machine", "facade", "blob", "foliage", "terrain"};
  return kinds;
}

Mesh procedural_mesh(const std::string& kind, int64_t triangles, uint64_t seed) {
  Mesh m;
  if (kind == "machine") m = machine(triangles, seed);
  else if (kind == "facade") m = facade(triangles, seed);
  else if (kind == "blob") m = blob(triangles, seed);
  else if (kind == "foliage") m = foliage(triangles, seed);
  else if (kind == "terrain") m = terrain(triangles, seed);
  else fail("gen-mesh: unknown --kind '", kind, "'");
  m.materials.resize(1);
  m.materials[0].name = kind;
  m.materials[0].base_color_factor = glm::vec4(0.6f, 0.6f, 0.6f, 1.0f);
  m.materials[0].metallic = 0.0f;
  m.materials[0].roughness = 0.5f;
  m.material_ids.assign(m.triangles.size(), 0);
  m.compute_vertex_normals();
  return m;
}

}  // namespace sl::bench
