/* The Embree side of deploy/bench-embree.sh: reads the triangles and rays written by
 * core/examples/embree_rays.rs, builds one Embree 3 scene (default build quality),
 * and times rtcIntersect1 over the primary rays and rtcOccluded1 over the occlusion rays
 * on one thread, then rtcIntersect8 and rtcOccluded8 over the same rays in packets of 8
 * consecutive ones (magg's packets hold 16). Prints "embree primary MRAYS occlusion MRAYS hits
 * P O packets MRAYS MRAYS" (median of the repeats, after one warm-up run). */
#include <embree3/rtcore.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + t.tv_nsec * 1e-9;
}

static int cmp(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

static RTCScene scene;
static float *rays;

static long primary(uint32_t n) {
  long hits = 0;
  struct RTCIntersectContext ctx;
  for (uint32_t i = 0; i < n; i++) {
    const float *r = rays + 7 * (size_t)i;
    struct RTCRayHit rh = {0};
    rh.ray.org_x = r[0]; rh.ray.org_y = r[1]; rh.ray.org_z = r[2];
    rh.ray.dir_x = r[3]; rh.ray.dir_y = r[4]; rh.ray.dir_z = r[5];
    rh.ray.tnear = 0.0f; rh.ray.tfar = r[6]; rh.ray.mask = 0xffffffff;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcInitIntersectContext(&ctx);
    rtcIntersect1(scene, &ctx, &rh);
    hits += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
  }
  return hits;
}

static long occlusion(uint32_t first, uint32_t n) {
  long hits = 0;
  struct RTCIntersectContext ctx;
  for (uint32_t i = first; i < first + n; i++) {
    const float *r = rays + 7 * (size_t)i;
    struct RTCRay ray = {0};
    ray.org_x = r[0]; ray.org_y = r[1]; ray.org_z = r[2];
    ray.dir_x = r[3]; ray.dir_y = r[4]; ray.dir_z = r[5];
    ray.tnear = 0.0f; ray.tfar = r[6]; ray.mask = 0xffffffff;
    rtcInitIntersectContext(&ctx);
    rtcOccluded1(scene, &ctx, &ray);
    hits += ray.tfar < 0.0f; /* -inf when occluded */
  }
  return hits;
}

/* The same rays, W consecutive ones at a time (the last packet partly valid): 8 by
 * default, Embree's native width on AVX2 (rtcIntersect16 ran slower on the AVX2 machine
 * of docs/PERFORMANCE.md); cc -DW=16 for 16. */
#ifndef W
#define W 8
#endif
#if W == 16
#define PACKET_HIT RTCRayHit16
#define PACKET_RAY RTCRay16
#define PACKET_INTERSECT rtcIntersect16
#define PACKET_OCCLUDED rtcOccluded16
#elif W == 8
#define PACKET_HIT RTCRayHit8
#define PACKET_RAY RTCRay8
#define PACKET_INTERSECT rtcIntersect8
#define PACKET_OCCLUDED rtcOccluded8
#else
#error "W must be 8 or 16"
#endif
static long primary_packets(uint32_t n) {
  long hits = 0;
  struct RTCIntersectContext ctx;
  for (uint32_t i = 0; i < n; i += W) {
    _Alignas(64) struct PACKET_HIT rh;
    _Alignas(64) int valid[W];
    for (int k = 0; k < W; k++) {
      uint32_t j = i + k < n ? i + k : i;
      const float *r = rays + 7 * (size_t)j;
      valid[k] = i + k < n ? -1 : 0;
      rh.ray.org_x[k] = r[0]; rh.ray.org_y[k] = r[1]; rh.ray.org_z[k] = r[2];
      rh.ray.dir_x[k] = r[3]; rh.ray.dir_y[k] = r[4]; rh.ray.dir_z[k] = r[5];
      rh.ray.tnear[k] = 0.0f; rh.ray.tfar[k] = r[6]; rh.ray.mask[k] = 0xffffffff;
      rh.ray.time[k] = 0.0f; rh.ray.flags[k] = 0;
      rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
    }
    rtcInitIntersectContext(&ctx);
    PACKET_INTERSECT(valid, scene, &ctx, &rh);
    for (int k = 0; k < W; k++) hits += valid[k] && rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID;
  }
  return hits;
}

static long occlusion_packets(uint32_t first, uint32_t n) {
  long hits = 0;
  struct RTCIntersectContext ctx;
  for (uint32_t i = 0; i < n; i += W) {
    _Alignas(64) struct PACKET_RAY ray;
    _Alignas(64) int valid[W];
    for (int k = 0; k < W; k++) {
      uint32_t j = first + (i + k < n ? i + k : i);
      const float *r = rays + 7 * (size_t)j;
      valid[k] = i + k < n ? -1 : 0;
      ray.org_x[k] = r[0]; ray.org_y[k] = r[1]; ray.org_z[k] = r[2];
      ray.dir_x[k] = r[3]; ray.dir_y[k] = r[4]; ray.dir_z[k] = r[5];
      ray.tnear[k] = 0.0f; ray.tfar[k] = r[6]; ray.mask[k] = 0xffffffff;
      ray.time[k] = 0.0f; ray.flags[k] = 0;
    }
    rtcInitIntersectContext(&ctx);
    PACKET_OCCLUDED(valid, scene, &ctx, &ray);
    for (int k = 0; k < W; k++) hits += valid[k] && ray.tfar[k] < 0.0f;
  }
  return hits;
}

int main(int argc, char **argv) {
  if (argc < 2) {
    fprintf(stderr, "usage: harness RAYS.bin [REPEATS]\n");
    return 2;
  }
  int repeats = argc > 2 ? atoi(argv[2]) : 5;
  if (repeats < 1) repeats = 1;
  FILE *f = fopen(argv[1], "rb");
  uint32_t head[3];
  if (!f || fread(head, 4, 3, f) != 3) {
    fprintf(stderr, "harness: cannot read %s\n", argv[1]);
    return 1;
  }
  uint32_t nt = head[0], np = head[1], no = head[2];
  float *tris = malloc(36 * (size_t)nt);
  rays = malloc(28 * ((size_t)np + no));
  if (!tris || !rays || fread(tris, 36, nt, f) != nt || fread(rays, 28, (size_t)np + no, f) != (size_t)np + no) {
    fprintf(stderr, "harness: %s is short\n", argv[1]);
    return 1;
  }
  fclose(f);
  for (size_t i = 0; i < (size_t)np + no; i++)
    if (isinf(rays[7 * i + 6])) rays[7 * i + 6] = INFINITY;

  RTCDevice dev = rtcNewDevice("threads=1");
  scene = rtcNewScene(dev);
  RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
  float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, 3 * (size_t)nt);
  unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, nt);
  for (size_t i = 0; i < 9 * (size_t)nt; i++) vb[i] = tris[i];
  for (size_t i = 0; i < 3 * (size_t)nt; i++) ib[i] = (unsigned)i;
  rtcCommitGeometry(g);
  rtcAttachGeometry(scene, g);
  rtcReleaseGeometry(g);
  rtcCommitScene(scene);

  double *tp = malloc(sizeof(double) * repeats), *to = malloc(sizeof(double) * repeats);
  long hp = primary(np), ho = occlusion(np, no);
  for (int k = 0; k < repeats; k++) {
    double t = now();
    primary(np);
    tp[k] = now() - t;
    t = now();
    occlusion(np, no);
    to[k] = now() - t;
  }
  qsort(tp, repeats, sizeof(double), cmp);
  qsort(to, repeats, sizeof(double), cmp);
  double rp = np / tp[repeats / 2] / 1e6, ro = no / to[repeats / 2] / 1e6;
  long hp8 = primary_packets(np), ho8 = occlusion_packets(np, no);
  for (int k = 0; k < repeats; k++) {
    double t = now();
    primary_packets(np);
    tp[k] = now() - t;
    t = now();
    occlusion_packets(np, no);
    to[k] = now() - t;
  }
  qsort(tp, repeats, sizeof(double), cmp);
  qsort(to, repeats, sizeof(double), cmp);
  if (hp8 != hp || ho8 != ho) fprintf(stderr, "harness: packets hit %ld %ld, single rays %ld %ld\n", hp8, ho8, hp, ho);
  printf("embree triangles %u primary %.3f occlusion %.3f hits %ld %ld packets %.3f %.3f\n", nt, rp, ro, hp, ho,
         np / tp[repeats / 2] / 1e6, no / to[repeats / 2] / 1e6);
  rtcReleaseScene(scene);
  rtcReleaseDevice(dev);
  return 0;
}
