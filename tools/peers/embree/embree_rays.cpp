// Embree peer of `cargo bench --bench ray_casting`: closest-hit (rtcIntersect1) and occlusion
// (rtcOccluded1) rays per second, one ray at a time in a loop, one thread, on the mesh and the
// ray sets the bench writes with RAY_CASTING_DUMP=path. Times are on-CPU times of the thread
// around the loop only, best of five passes (as the bench's). Builds against Embree 3 or 4
// (see README.md and run.sh).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
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

static const char *NAMES[] = {"outside -> sphere", "inside, to the boundary", "inside, short (s_t = 24)"};

int main(int argc, char **argv) {
  if (argc < 2) { fprintf(stderr, "usage: %s DUMP [embree config]\n", argv[0]); return 2; }
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
  RTCScene scene = rtcNewScene(dev);
  rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
  // EMBREE_ROBUST=1: Embree's robust mode (conservative traversal, no accuracy-reducing
  // shortcuts), the mode closest to velour's watertight test; the default is the fast mode.
  const char *robust = getenv("EMBREE_ROBUST");
  bool robust_mode = robust && robust[0] == '1';
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
  long v = (long)rtcGetDeviceProperty(dev, RTC_DEVICE_PROPERTY_VERSION);
  printf("embree %ld.%ld.%ld (headers %s), %s mode: %u triangles\n", v / 10000, v / 100 % 100, v % 100, RTC_VERSION_STRING, robust_mode ? "robust" : "fast", nt);
  printf("%-28s %14s %14s\n", "rays", "embree closest", "embree occl.");

#if !EMBREE4
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
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
        const float *q = &s[7 * i];
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
        rtcIntersect1(scene, &ctx, &rh);
#endif
        if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) { hits_c++; tsum += rh.ray.tfar; }
      }
      double dt = thread_cpu() - t0;
      if (dt < best_c) best_c = dt;
      hits_o = 0;
      t0 = thread_cpu();
      for (size_t i = 0; i < n; i++) {
        const float *q = &s[7 * i];
        RTCRay ray;
        ray.org_x = q[0]; ray.org_y = q[1]; ray.org_z = q[2];
        ray.dir_x = q[3]; ray.dir_y = q[4]; ray.dir_z = q[5];
        ray.tnear = 0.0f; ray.tfar = q[6];
        ray.mask = 0xFFFFFFFF; ray.flags = 0; ray.time = 0.0f;
#if EMBREE4
        rtcOccluded1(scene, &ray);
#else
        rtcOccluded1(scene, &ctx, &ray);
#endif
        hits_o += ray.tfar < 0.0f;  // Embree sets tfar to -inf on a hit
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
