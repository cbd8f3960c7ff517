/* Embree's occlusion queries on the rays `examples/kernel_rays.rs` wrote, timed the same four
 * ways on one thread: rtcOccluded1 in point order and shuffled, rtcOccluded16 on 16 consecutive
 * rays in point order and in sample order. Built and run by scripts/compare-kernels.sh.
 *
 *   embree_kernel RAYS.bin [ROUNDS]
 *
 * Two Embree builds: by default Embree 4 from the peers' embreex wheel, which ships libembree4
 * without its headers, so the few declarations used are written out here from Embree 4's
 * rtcore*.h (the layouts of RTCRay and RTCRay16, the enum values of a triangle geometry with a
 * float3 vertex and uint3 index buffer). Compiled as C++ with MITSUBA_EMBREE3 defined: the
 * Embree 3 that Mitsuba's wheel ships with its headers (its API in namespace `mitsuba`, each
 * query taking an intersect context), the scene built at RTC_BUILD_QUALITY_HIGH (spatial
 * splits) as Mitsuba builds its scenes, or MEDIUM with the environment variable
 * EMBREE_QUALITY=medium. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#ifdef MITSUBA_EMBREE3
#include <embree3/rtcore.h>
using namespace mitsuba;
static void occluded1(RTCScene scene, RTCRay *ray) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    rtcOccluded1(scene, &context, ray);
}
static void occluded16(const int *valid, RTCScene scene, RTCRay16 *rays) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    rtcOccluded16(valid, scene, &context, rays);
}
static void set_quality(RTCScene scene) {
    const char *q = getenv("EMBREE_QUALITY");
    rtcSetSceneBuildQuality(scene, q && !strcmp(q, "medium") ? RTC_BUILD_QUALITY_MEDIUM : RTC_BUILD_QUALITY_HIGH);
}
#define ENGINE "embree3"
#else
typedef struct RTCDeviceTy *RTCDevice;
typedef struct RTCSceneTy *RTCScene;
typedef struct RTCGeometryTy *RTCGeometry;
enum { RTC_GEOMETRY_TYPE_TRIANGLE = 0, RTC_BUFFER_TYPE_INDEX = 0, RTC_BUFFER_TYPE_VERTEX = 1 };
enum { RTC_FORMAT_UINT3 = 0x5003, RTC_FORMAT_FLOAT3 = 0x9003 };
RTCDevice rtcNewDevice(const char *config);
int rtcGetDeviceError(RTCDevice device);
RTCScene rtcNewScene(RTCDevice device);
RTCGeometry rtcNewGeometry(RTCDevice device, int type);
void *rtcSetNewGeometryBuffer(RTCGeometry geometry, int type, unsigned slot, int format, size_t byte_stride,
                              size_t item_count);
void rtcCommitGeometry(RTCGeometry geometry);
unsigned rtcAttachGeometry(RTCScene scene, RTCGeometry geometry);
void rtcReleaseGeometry(RTCGeometry geometry);
void rtcCommitScene(RTCScene scene);
typedef struct __attribute__((aligned(16))) {
    float org_x, org_y, org_z, tnear, dir_x, dir_y, dir_z, time, tfar;
    unsigned mask, id, flags;
} RTCRay;
typedef struct __attribute__((aligned(64))) {
    float org_x[16], org_y[16], org_z[16], tnear[16], dir_x[16], dir_y[16], dir_z[16], time[16], tfar[16];
    unsigned mask[16], id[16], flags[16];
} RTCRay16;
void rtcOccluded1(RTCScene scene, RTCRay *ray, void *args);
void rtcOccluded16(const int *valid, RTCScene scene, RTCRay16 *ray, void *args);
static void occluded1(RTCScene scene, RTCRay *ray) { rtcOccluded1(scene, ray, NULL); }
static void occluded16(const int *valid, RTCScene scene, RTCRay16 *rays) { rtcOccluded16(valid, scene, rays, NULL); }
static void set_quality(RTCScene scene) { (void)scene; }
#define ENGINE "embree"
#endif

static const float *rays;
static float length = INFINITY;

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

/* Ray k of the file, as an RTCRay of the file's ray length. */
static RTCRay ray1(uint64_t k) {
    const float *r = rays + 6 * k;
    RTCRay ray = {r[0], r[1], r[2], 0.0f, r[3], r[4], r[5], 0.0f, length, ~0u, 0, 0};
    return ray;
}

/* Blocked rays among `n`, traced one at a time in the order `order` (NULL: file order). */
static uint64_t single(RTCScene scene, uint64_t n, const uint32_t *order) {
    uint64_t blocked = 0;
    for (uint64_t i = 0; i < n; i++) {
        RTCRay ray = ray1(order ? order[i] : i);
        occluded1(scene, &ray);
        blocked += ray.tfar < 0.0f;
    }
    return blocked;
}

/* Blocked rays among `n`, traced 16 at a time; ray i of the order is file ray index(i). */
static uint64_t packets(RTCScene scene, uint64_t n, uint64_t per_point, int sample_order) {
    uint64_t blocked = 0, points = n / per_point;
    for (uint64_t first = 0; first < n; first += 16) {
        RTCRay16 p;
        int valid[16];
        for (int l = 0; l < 16; l++) {
            uint64_t i = first + l;
            valid[l] = i < n ? -1 : 0;
            uint64_t k = i < n ? (sample_order ? (i % points) * per_point + i / points : i) : 0;
            RTCRay r = ray1(k);
            p.org_x[l] = r.org_x, p.org_y[l] = r.org_y, p.org_z[l] = r.org_z, p.tnear[l] = 0.0f;
            p.dir_x[l] = r.dir_x, p.dir_y[l] = r.dir_y, p.dir_z[l] = r.dir_z, p.time[l] = 0.0f;
            p.tfar[l] = r.tfar, p.mask[l] = ~0u, p.id[l] = 0, p.flags[l] = 0;
        }
        occluded16(valid, scene, &p);
        for (int l = 0; l < 16; l++) blocked += valid[l] && p.tfar[l] < 0.0f;
    }
    return blocked;
}

static int read_all(FILE *f, void *to, size_t size, size_t count) { return fread(to, size, count, f) == count; }

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: embree_kernel RAYS.bin [ROUNDS]\n");
        return 2;
    }
    int rounds = argc > 2 ? atoi(argv[2]) : 3;
    FILE *f = fopen(argv[1], "rb");
    uint64_t tris, n;
    uint32_t per_point;
    if (!f || !read_all(f, &tris, 8, 1)) return fprintf(stderr, "embree_kernel: cannot read %s\n", argv[1]), 1;
    float *v = (float *)malloc(tris * 36);
    if (!v || !read_all(f, v, 36, tris) || !read_all(f, &n, 8, 1) || !read_all(f, &per_point, 4, 1) || !per_point)
        return fprintf(stderr, "embree_kernel: %s is truncated\n", argv[1]), 1;
    float *r = (float *)malloc(n * 24);
    uint32_t *order = (uint32_t *)malloc(n * 4);
    if (!r || !order || !read_all(f, r, 24, n) || !read_all(f, order, 4, n) || !read_all(f, &length, 4, 1))
        return fprintf(stderr, "embree_kernel: %s is truncated\n", argv[1]), 1;
    fclose(f);
    rays = r;

    RTCDevice device = rtcNewDevice("threads=1");
    RTCScene scene = rtcNewScene(device);
    set_quality(scene);
    RTCGeometry mesh = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    float *vb = (float *)rtcSetNewGeometryBuffer(mesh, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, 3 * tris);
    unsigned *ib = (unsigned *)rtcSetNewGeometryBuffer(mesh, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, tris);
    if (!vb || !ib) return fprintf(stderr, "embree_kernel: embree error %d\n", rtcGetDeviceError(device)), 1;
    for (uint64_t i = 0; i < 9 * tris; i++) vb[i] = v[i];
    for (uint64_t i = 0; i < 3 * tris; i++) ib[i] = (unsigned)i;
    rtcCommitGeometry(mesh);
    rtcAttachGeometry(scene, mesh);
    rtcReleaseGeometry(mesh);
    rtcCommitScene(scene);
    if (rtcGetDeviceError(device)) return fprintf(stderr, "embree_kernel: embree error %d\n", rtcGetDeviceError(device)), 1;

    double best[4] = {INFINITY, INFINITY, INFINITY, INFINITY};
    uint64_t blocked[4] = {0};
    for (int round = 0; round < rounds; round++) {
        for (int way = 0; way < 4; way++) {
            double t = now();
            blocked[way] = way == 0   ? single(scene, n, NULL)
                           : way == 1 ? single(scene, n, order)
                                      : packets(scene, n, per_point, way == 3);
            t = now() - t;
            if (t < best[way]) best[way] = t;
        }
    }
    for (int way = 1; way < 4; way++)
        if (blocked[way] != blocked[0]) return fprintf(stderr, "embree_kernel: the orders disagree\n"), 1;
    printf(ENGINE " %lu rays, %lu blocked; Mrays/s, one thread: single %.2f, single shuffled %.2f, "
           "packets of 16 (point order) %.2f, packets of 16 (sample order) %.2f\n",
           (unsigned long)n, (unsigned long)blocked[0], n / best[0] / 1e6, n / best[1] / 1e6, n / best[2] / 1e6,
           n / best[3] / 1e6);
    return 0;
}
