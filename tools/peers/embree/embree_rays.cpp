// Embree peer of `cargo bench --bench ray_casting`: closest-hit (rtcIntersect1) and occlusion
// (rtcOccluded1) rays per second, one ray at a time in a loop, one thread, on the mesh and the
// ray sets the bench writes with RAY_CASTING_DUMP=path. Times are on-CPU times of the thread
// around the loop only, best of five passes (as the bench's). Builds against Embree 3 or 4
// (see README.md and run.sh).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <vector>
#if EMBREE4
#include <embree4/rtcore.h>
#else
#include <embree3/rtcore.h>
#endif

static double thread_cpu() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + ts.tv_nsec * 1e-9;
}

struct Reader {
  FILE *f;
  uint32_t u32() {
    uint32_t v;
    if (fread(&v, 4, 1, f) != 1) { fprintf(stderr, "short dump\n"); exit(1); }
    return v;
  }
  void f32s(float *p, size_t n) {
    if (fread(p, 4, n, f) != n) { fprintf(stderr, "short dump\n"); exit(1); }
  }
};

// ---- Recorded queries (velour's ray log, `src/geometry/ray_log.rs`; magic VRAYLOG1) ----

struct Query {
  uint8_t kind, flags;  // kind: 0 closest, 1 occlusion, 2 closest-and-beyond; flags: bit 0 hit
  float q[7];           // origin xyz, direction xyz, t_max
  float t;              // recorded hit distance
  uint32_t prim;        // recorded hit triangle in the merged mesh (UINT32_MAX: none)
};

struct Log {
  std::vector<float> pos;
  std::vector<uint32_t> idx;
  std::vector<Query> queries;
  uint64_t seen = 0;
  uint32_t every = 1;
};

static bool read_log(const char *path, Log &log) {
  FILE *f = fopen(path, "rb");
  if (!f) { perror(path); exit(1); }
  char magic[8];
  if (fread(magic, 1, 8, f) != 8 || memcmp(magic, "VRAYLOG1", 8) != 0) { fclose(f); return false; }
  Reader r{f};
  uint32_t nm = r.u32();
  std::vector<std::pair<uint32_t, uint32_t>> first_prim;  // (shape, first merged triangle)
  for (uint32_t m = 0; m < nm; m++) {
    uint32_t shape = r.u32();
    uint32_t base = log.pos.size() / 3;
    first_prim.push_back({shape, (uint32_t)(log.idx.size() / 3)});
    uint32_t nv = r.u32();
    size_t at = log.pos.size();
    log.pos.resize(at + 3 * (size_t)nv);
    r.f32s(&log.pos[at], 3 * (size_t)nv);
    uint32_t nt = r.u32();
    for (size_t i = 0; i < 3 * (size_t)nt; i++) log.idx.push_back(base + r.u32());
  }
  uint32_t lo = r.u32(), hi = r.u32();
  log.seen = lo | (uint64_t)hi << 32;
  log.every = r.u32();
  lo = r.u32(); hi = r.u32();
  uint64_t n = lo | (uint64_t)hi << 32;
  log.queries.resize(n);
  for (auto &q : log.queries) {
    uint8_t head[4];
    if (fread(head, 1, 4, f) != 4) { fprintf(stderr, "short log\n"); exit(1); }
    q.kind = head[0]; q.flags = head[1];
    r.f32s(q.q, 7);
    r.f32s(&q.t, 1);
    uint32_t shape = r.u32(), prim = r.u32();
    q.prim = UINT32_MAX;
    if ((q.flags & 1) && q.kind != 1)
      for (auto &fp : first_prim) if (fp.first == shape) q.prim = fp.second + prim;
  }
  fclose(f);
  return true;
}

// The bucket of velour's bench (`bucket` in benches/ray_casting.rs): kind * 5 + class, class 0
// unbounded from outside the mesh's bounding box, 1 unbounded from inside it, 2 t_max < 0.1,
// 3 t_max < 1, 4 finite t_max >= 1.
static int bucket(const Query &q, const float lo[3], const float hi[3]) {
  int c;
  if (q.q[6] == INFINITY) {
    bool in = true;
    for (int a = 0; a < 3; a++) in = in && q.q[a] >= lo[a] && q.q[a] <= hi[a];
    c = in ? 1 : 0;
  } else {
    c = q.q[6] < 0.1f ? 2 : q.q[6] < 1.0f ? 3 : 4;
  }
  return q.kind * 5 + c;
}

static const char *CLASS_NAMES[] = {"t_max = inf, from outside", "t_max = inf, from inside box", "t_max < 0.1",
                                    "0.1 <= t_max < 1", "t_max finite >= 1"};
static const char *KIND_NAMES[] = {"closest", "occlusion", "beyond"};

static RTCScene build_scene(RTCDevice dev, const std::vector<float> &pos, const std::vector<uint32_t> &idx, bool robust_mode);

#if !EMBREE4
static RTCIntersectContext g_ctx;
#endif

// Closest hit: primID (UINT32_MAX: none), distance in *t.
static inline uint32_t closest(RTCScene scene, const float *q, float *t) {
  RTCRayHit rh;
  rh.ray.org_x = q[0]; rh.ray.org_y = q[1]; rh.ray.org_z = q[2];
  rh.ray.dir_x = q[3]; rh.ray.dir_y = q[4]; rh.ray.dir_z = q[5];
  rh.ray.tnear = 0.0f; rh.ray.tfar = q[6];
  rh.ray.mask = 0xFFFFFFFF; rh.ray.flags = 0; rh.ray.time = 0.0f;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
#if EMBREE4
  rtcIntersect1(scene, &rh);
#else
  rtcIntersect1(scene, &g_ctx, &rh);
#endif
  *t = rh.ray.tfar;
  return rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? UINT32_MAX : rh.hit.primID;
}

static inline bool occluded(RTCScene scene, const float *q) {
  RTCRay ray;
  ray.org_x = q[0]; ray.org_y = q[1]; ray.org_z = q[2];
  ray.dir_x = q[3]; ray.dir_y = q[4]; ray.dir_z = q[5];
  ray.tnear = 0.0f; ray.tfar = q[6];
  ray.mask = 0xFFFFFFFF; ray.flags = 0; ray.time = 0.0f;
#if EMBREE4
  rtcOccluded1(scene, &ray);
#else
  rtcOccluded1(scene, &g_ctx, &ray);
#endif
  return ray.tfar < 0.0f;  // Embree sets tfar to -inf on a hit
}

// Rays per second over `qs` (7 floats and a kind each), best of five passes: mode 0 as
// recorded (closest-hit for closest and beyond queries, occlusion for occlusion ones), 1 every
// query as a closest-hit query, 2 every query as an occlusion query.
static double rate(RTCScene scene, const std::vector<Query> &qs, int mode, size_t *hits) {
  double best = INFINITY;
  for (int pass = 0; pass < 5; pass++) {
    size_t h = 0;
    double t0 = thread_cpu();
    for (const Query &q : qs) {
      float t;
      if (mode == 2 || (mode == 0 && q.kind == 1)) h += occluded(scene, q.q);
      else h += closest(scene, q.q, &t) != UINT32_MAX;
    }
    double dt = thread_cpu() - t0;
    if (dt < best) best = dt;
    *hits = h;
  }
  return qs.size() / best;
}

static int run_log(const Log &log, const char *config) {
  RTCDevice dev = rtcNewDevice(config);
  const char *robust = getenv("EMBREE_ROBUST");
  bool robust_mode = robust && robust[0] == '1';
  RTCScene scene = build_scene(dev, log.pos, log.idx, robust_mode);
#if !EMBREE4
  rtcInitIntersectContext(&g_ctx);
#endif
  long v = (long)rtcGetDeviceProperty(dev, RTC_DEVICE_PROPERTY_VERSION);
  printf("embree %ld.%ld.%ld (headers %s), %s mode: %zu triangles; recorded: %zu queries of %llu (every %u)\n",
         v / 10000, v / 100 % 100, v % 100, RTC_VERSION_STRING, robust_mode ? "robust" : "fast", log.idx.size() / 3,
         log.queries.size(), (unsigned long long)log.seen, log.every);
  // Untimed: Embree's answers against velour's recorded ones. A closest-hit or beyond query
  // recorded velour's closest hit; an occlusion query whether anything was hit.
  size_t hit_diff = 0, prim_diff = 0, occl_diff = 0, compared = 0;
  double max_rel_t = 0, max_abs_t = 0;
  size_t same_t = 0, hits = 0;
  for (const Query &q : log.queries) {
    bool rec_hit = q.flags & 1;
    if (q.kind != 1) {
      float t;
      uint32_t prim = closest(scene, q.q, &t);
      compared++;
      if ((prim != UINT32_MAX) != rec_hit) hit_diff++;
      else if (rec_hit && prim != q.prim) prim_diff++;
      else if (rec_hit) {
        double d = fabs((double)t - q.t), rel = d / fabs((double)q.t);
        if (rel > max_rel_t) max_rel_t = rel;
        if (d > max_abs_t) max_abs_t = d;
        same_t += t == q.t;
        hits++;
      }
    }
    if (occluded(scene, q.q) != rec_hit) occl_diff++;
  }
  printf("against velour's recorded answers: %zu of %zu closest hits differ in hit/miss, %zu in the triangle; "
         "occlusion differs on %zu of %zu; of %zu common hits %zu have the same distance, the largest difference "
         "%.3g (relative %.3g)\n",
         hit_diff, compared, prim_diff, occl_diff, log.queries.size(), hits, same_t, max_abs_t, max_rel_t);
  float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < log.pos.size(); i++) {
    lo[i % 3] = fminf(lo[i % 3], log.pos[i]);
    hi[i % 3] = fmaxf(hi[i % 3], log.pos[i]);
  }
  std::vector<std::vector<Query>> buckets(15);
  for (const Query &q : log.queries) buckets[bucket(q, lo, hi)].push_back(q);
  printf("%-38s %9s %7s %14s %14s %14s   hits (as recorded / closest / occl.)\n", "rays", "count", "share",
         "embree as rec.", "embree closest", "embree occl.");
  auto row = [&](const char *name, const std::vector<Query> &qs) {
    size_t hr, hc, ho;
    double r = rate(scene, qs, 0, &hr), c = rate(scene, qs, 1, &hc), o = rate(scene, qs, 2, &ho);
    printf("%-38s %9zu %6.1f%% %12.2f M %12.2f M %12.2f M   (%zu / %zu / %zu)\n", name, qs.size(),
           100.0 * qs.size() / log.queries.size(), r / 1e6, c / 1e6, o / 1e6, hr, hc, ho);
  };
  row("whole mix", log.queries);
  for (int b = 0; b < 15; b++) {
    if (buckets[b].empty()) continue;
    char name[96];
    snprintf(name, sizeof name, "%s, %s", KIND_NAMES[b / 5], CLASS_NAMES[b % 5]);
    row(name, buckets[b]);
  }
  rtcReleaseScene(scene);
  rtcReleaseDevice(dev);
  return 0;
}

static const char *NAMES[] = {"outside -> sphere", "inside, to the boundary", "inside, short (s_t = 24)"};

int main(int argc, char **argv) {
  if (argc < 2) { fprintf(stderr, "usage: %s DUMP [embree config]\n", argv[0]); return 2; }
  {
    Log log;
    if (read_log(argv[1], log)) return run_log(log, argc > 2 ? argv[2] : "threads=1");
  }
  FILE *f = fopen(argv[1], "rb");
  if (!f) { perror(argv[1]); return 1; }
  Reader r{f};
  uint32_t nv = r.u32();
  std::vector<float> pos(3 * nv);
  r.f32s(pos.data(), pos.size());
  uint32_t nt = r.u32();
  std::vector<uint32_t> idx(3 * nt);
  for (auto &i : idx) i = r.u32();
  uint32_t nsets = r.u32();
  std::vector<std::vector<float>> sets(nsets);
  for (auto &s : sets) {
    uint32_t n = r.u32();
    s.resize(7 * (size_t)n);
    r.f32s(s.data(), s.size());
  }
  fclose(f);

  // Default config: the best build quality Embree offers for a static scene, one thread
  // for the traversal (the build's threads are not timed).
  RTCDevice dev = rtcNewDevice(argc > 2 ? argv[2] : "threads=1");
  const char *robust = getenv("EMBREE_ROBUST");
  bool robust_mode = robust && robust[0] == '1';
  RTCScene scene = build_scene(dev, pos, idx, robust_mode);
  long v = (long)rtcGetDeviceProperty(dev, RTC_DEVICE_PROPERTY_VERSION);
  printf("embree %ld.%ld.%ld (headers %s), %s mode: %u triangles\n", v / 10000, v / 100 % 100, v % 100, RTC_VERSION_STRING, robust_mode ? "robust" : "fast", nt);
  printf("%-28s %14s %14s\n", "rays", "embree closest", "embree occl.");

#if !EMBREE4
  rtcInitIntersectContext(&g_ctx);
#endif
  // RAY_CASTING_SET=k: only set k (as velour's bench; for per-set callgrind counts).
  const char *only = getenv("RAY_CASTING_SET");
  for (uint32_t k = 0; k < nsets; k++) {
    if (only && (uint32_t)atoi(only) != k) continue;
    const std::vector<float> &s = sets[k];
    size_t n = s.size() / 7;
    double best_c = INFINITY, best_o = INFINITY, tsum = 0;
    size_t hits_c = 0, hits_o = 0;
    for (int pass = 0; pass < 5; pass++) {
      hits_c = 0;
      tsum = 0;
      double t0 = thread_cpu();
      for (size_t i = 0; i < n; i++) {
        float t;
        if (closest(scene, &s[7 * i], &t) != UINT32_MAX) { hits_c++; tsum += t; }
      }
      double dt = thread_cpu() - t0;
      if (dt < best_c) best_c = dt;
      hits_o = 0;
      t0 = thread_cpu();
      for (size_t i = 0; i < n; i++) {
        hits_o += occluded(scene, &s[7 * i]);
      }
      dt = thread_cpu() - t0;
      if (dt < best_o) best_o = dt;
    }
    printf("%-28s %12.2f M %12.2f M   (hits %zu / occluded %zu, mean t %.6f)\n", k < 3 ? NAMES[k] : "set",
           n / best_c / 1e6, n / best_o / 1e6, hits_c, hits_o, hits_c ? tsum / hits_c : 0.0);
  }
  rtcReleaseScene(scene);
  rtcReleaseDevice(dev);
  return 0;
}

// One triangle geometry over `pos` / `idx`, the best build quality Embree offers for a static
// scene. robust_mode (EMBREE_ROBUST=1): Embree's robust mode (conservative traversal, no
// accuracy-reducing shortcuts), the mode closest to velour's watertight test; the default is
// the fast mode.
static RTCScene build_scene(RTCDevice dev, const std::vector<float> &pos, const std::vector<uint32_t> &idx,
                            bool robust_mode) {
  size_t nv = pos.size() / 3, nt = idx.size() / 3;
  RTCScene scene = rtcNewScene(dev);
  rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
  rtcSetSceneFlags(scene, robust_mode ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE);
  RTCGeometry geom = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetGeometryBuildQuality(geom, RTC_BUILD_QUALITY_HIGH);
  float *vb = (float *)rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                               3 * sizeof(float), nv);
  for (size_t i = 0; i < pos.size(); i++) vb[i] = pos[i];
  uint32_t *ib = (uint32_t *)rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                     3 * sizeof(uint32_t), nt);
  for (size_t i = 0; i < idx.size(); i++) ib[i] = idx[i];
  rtcCommitGeometry(geom);
  rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(scene);
  return scene;
}
