/*
 * A C program that embeds ember through its C API (kernel/include/ember.h, libember_capi.a).
 * It loads nothing from disk: it builds the Cornell box of the determinism checks
 * (tests/determinism/src/lib.rs, same literal quads, materials, texels and texture
 * coordinates: diffuse, Phong and mixture boxes, a mirror, a rough metal panel, a glass box
 * with a frosted face, a textured floor and a textured Phong picture) in arrays, builds the
 * binary BVH, the wide acceleration structure and the emitter table into its own buffers,
 * renders the box (traced with the acceleration structure) with each path integrator
 * from two threads (pthreads, the top and bottom halves, each in 8x8 tiles), renders it with
 * the light tracer and BDPT (power and balance heuristics) the same way, each thread adding
 * its splats to its own splat buffer, merges the two buffers and resolves the images, bakes a
 * few points, checks that the binary BVH gives the same pixels and baked values, checks the
 * ABI version and that bad input (old-layout records and damaged acceleration structures
 * included) gets error codes, and prints the FNV-1a hashes of the pixels and of the baked values. With an
 * argument it also writes every array and result to that file (raw little-endian), which
 * tests/tests/capi.rs compares bit for bit with the Rust API's.
 *
 * The rendering threads run on stacks of exactly EMBER_STACK_BYTES that this program
 * allocates above a guard page and fills with a pattern (pthread_attr_setstack); after each
 * join it measures how deep the pattern was overwritten and fails if a thread used more than
 * half of it (the header's margin). It prints the deepest use as `stack <bytes>` (on stderr).
 *
 *   cc -std=c11 -O2 -pthread -I kernel/include tests/capi/cornell.c libember_capi.a \
 *      -lpthread -ldl -lm -o cornell && ./cornell [OUT.bin]
 */
/* pthread_attr_setstack is POSIX.1-2001; -std=c11 alone does not declare it. */
#define _POSIX_C_SOURCE 200809L

#include "ember.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#define WIDTH 32
#define HEIGHT 32
#define TILE 8
#define NQUADS 24
#define NVERTICES (4 * NQUADS)
#define NTRIANGLES (2 * NQUADS)
#define NMATERIALS 12
#define NTEXTURES 3
#define NTEXELS 36
#define NPOINTS 14

typedef struct Quad {
    float corners[4][3];
    float normal[3];
    uint32_t material;
} Quad;

/* The room with a textured floor, the light, a short mixture box, a tall Phong box, a mirror,
 * a rough metal panel, a textured Phong picture and a glass box (tests/determinism). */
static const Quad QUADS[NQUADS] = {
    {{{-1.0f, 0.0f, 1.0f}, {1.0f, 0.0f, 1.0f}, {1.0f, 0.0f, -1.0f}, {-1.0f, 0.0f, -1.0f}}, {0.0f, 1.0f, 0.0f}, 6},
    {{{-1.0f, 2.0f, -1.0f}, {1.0f, 2.0f, -1.0f}, {1.0f, 2.0f, 1.0f}, {-1.0f, 2.0f, 1.0f}}, {0.0f, -1.0f, 0.0f}, 0},
    {{{-1.0f, 0.0f, -1.0f}, {1.0f, 0.0f, -1.0f}, {1.0f, 2.0f, -1.0f}, {-1.0f, 2.0f, -1.0f}}, {0.0f, 0.0f, 1.0f}, 0},
    {{{-1.0f, 0.0f, 1.0f}, {-1.0f, 0.0f, -1.0f}, {-1.0f, 2.0f, -1.0f}, {-1.0f, 2.0f, 1.0f}}, {1.0f, 0.0f, 0.0f}, 1},
    {{{1.0f, 0.0f, -1.0f}, {1.0f, 0.0f, 1.0f}, {1.0f, 2.0f, 1.0f}, {1.0f, 2.0f, -1.0f}}, {-1.0f, 0.0f, 0.0f}, 2},
    {{{-0.25f, 1.98f, -0.25f}, {0.25f, 1.98f, -0.25f}, {0.25f, 1.98f, 0.25f}, {-0.25f, 1.98f, 0.25f}}, {0.0f, -1.0f, 0.0f}, 3},
    {{{-0.75f, 0.6f, 0.4f}, {-0.15f, 0.6f, 0.4f}, {-0.15f, 0.6f, -0.2f}, {-0.75f, 0.6f, -0.2f}}, {0.0f, 1.0f, 0.0f}, 5},
    {{{-0.75f, 0.0f, 0.4f}, {-0.15f, 0.0f, 0.4f}, {-0.15f, 0.6f, 0.4f}, {-0.75f, 0.6f, 0.4f}}, {0.0f, 0.0f, 1.0f}, 5},
    {{{-0.15f, 0.0f, -0.2f}, {-0.75f, 0.0f, -0.2f}, {-0.75f, 0.6f, -0.2f}, {-0.15f, 0.6f, -0.2f}}, {0.0f, 0.0f, -1.0f}, 5},
    {{{-0.75f, 0.0f, -0.2f}, {-0.75f, 0.0f, 0.4f}, {-0.75f, 0.6f, 0.4f}, {-0.75f, 0.6f, -0.2f}}, {-1.0f, 0.0f, 0.0f}, 5},
    {{{-0.15f, 0.0f, 0.4f}, {-0.15f, 0.0f, -0.2f}, {-0.15f, 0.6f, -0.2f}, {-0.15f, 0.6f, 0.4f}}, {1.0f, 0.0f, 0.0f}, 5},
    {{{0.1f, 1.2f, -0.1f}, {0.7f, 1.2f, -0.1f}, {0.7f, 1.2f, -0.7f}, {0.1f, 1.2f, -0.7f}}, {0.0f, 1.0f, 0.0f}, 4},
    {{{0.1f, 0.0f, -0.1f}, {0.7f, 0.0f, -0.1f}, {0.7f, 1.2f, -0.1f}, {0.1f, 1.2f, -0.1f}}, {0.0f, 0.0f, 1.0f}, 4},
    {{{0.7f, 0.0f, -0.7f}, {0.1f, 0.0f, -0.7f}, {0.1f, 1.2f, -0.7f}, {0.7f, 1.2f, -0.7f}}, {0.0f, 0.0f, -1.0f}, 4},
    {{{0.1f, 0.0f, -0.7f}, {0.1f, 0.0f, -0.1f}, {0.1f, 1.2f, -0.1f}, {0.1f, 1.2f, -0.7f}}, {-1.0f, 0.0f, 0.0f}, 4},
    {{{0.7f, 0.0f, -0.1f}, {0.7f, 0.0f, -0.7f}, {0.7f, 1.2f, -0.7f}, {0.7f, 1.2f, -0.1f}}, {1.0f, 0.0f, 0.0f}, 4},
    {{{-0.99f, 0.7f, 0.2f}, {-0.99f, 0.7f, -0.8f}, {-0.99f, 1.7f, -0.8f}, {-0.99f, 1.7f, 0.2f}}, {1.0f, 0.0f, 0.0f}, 7},
    {{{0.99f, 0.7f, -0.3f}, {0.99f, 0.7f, 0.7f}, {0.99f, 1.5f, 0.7f}, {0.99f, 1.5f, -0.3f}}, {-1.0f, 0.0f, 0.0f}, 8},
    {{{0.1f, 1.3f, -0.99f}, {0.9f, 1.3f, -0.99f}, {0.9f, 1.9f, -0.99f}, {0.1f, 1.9f, -0.99f}}, {0.0f, 0.0f, 1.0f}, 11},
    {{{-0.05f, 0.45f, 0.65f}, {0.4f, 0.45f, 0.65f}, {0.4f, 0.45f, 0.25f}, {-0.05f, 0.45f, 0.25f}}, {0.0f, 1.0f, 0.0f}, 9},
    {{{-0.05f, 0.0f, 0.65f}, {0.4f, 0.0f, 0.65f}, {0.4f, 0.45f, 0.65f}, {-0.05f, 0.45f, 0.65f}}, {0.0f, 0.0f, 1.0f}, 10},
    {{{0.4f, 0.0f, 0.25f}, {-0.05f, 0.0f, 0.25f}, {-0.05f, 0.45f, 0.25f}, {0.4f, 0.45f, 0.25f}}, {0.0f, 0.0f, -1.0f}, 9},
    {{{-0.05f, 0.0f, 0.25f}, {-0.05f, 0.0f, 0.65f}, {-0.05f, 0.45f, 0.65f}, {-0.05f, 0.45f, 0.25f}}, {-1.0f, 0.0f, 0.0f}, 9},
    {{{0.4f, 0.0f, 0.65f}, {0.4f, 0.0f, 0.25f}, {0.4f, 0.45f, 0.25f}, {0.4f, 0.45f, 0.65f}}, {1.0f, 0.0f, 0.0f}, 9},
};

/* Texture coordinates of every quad's corners, in corner order. */
static const float QUAD_UVS[4][2] = {{0.0f, 0.0f}, {1.0f, 0.0f}, {1.0f, 1.0f}, {0.0f, 1.0f}};

#define NONE EMBER_NO_TEXTURE
#define MAT sizeof(EmberMaterial)
/* struct_size, kind, kd, kd_texture, ks, ks_texture, ns, ke, ior, tf, alpha (roughness alpha,
 * not MTL Pr). Walls, light, Phong box, mixture box, textured floor, mirror, rough metal,
 * smooth glass, frosted glass, textured Phong picture. */
static const EmberMaterial MATERIALS[NMATERIALS] = {
    {MAT, EMBER_MATERIAL_DIFFUSE, {0.725f, 0.71f, 0.68f}, NONE, {0.0f, 0.0f, 0.0f}, NONE, 1.0f, {0.0f, 0.0f, 0.0f}, 1.0f, {1.0f, 1.0f, 1.0f}, 0.0f},
    {MAT, EMBER_MATERIAL_DIFFUSE, {0.63f, 0.065f, 0.05f}, NONE, {0.0f, 0.0f, 0.0f}, NONE, 1.0f, {0.0f, 0.0f, 0.0f}, 1.0f, {1.0f, 1.0f, 1.0f}, 0.0f},
    {MAT, EMBER_MATERIAL_DIFFUSE, {0.14f, 0.45f, 0.091f}, NONE, {0.0f, 0.0f, 0.0f}, NONE, 1.0f, {0.0f, 0.0f, 0.0f}, 1.0f, {1.0f, 1.0f, 1.0f}, 0.0f},
    {MAT, EMBER_MATERIAL_DIFFUSE, {0.0f, 0.0f, 0.0f}, NONE, {0.0f, 0.0f, 0.0f}, NONE, 1.0f, {17.0f, 12.0f, 4.0f}, 1.0f, {1.0f, 1.0f, 1.0f}, 0.0f},
    {MAT, EMBER_MATERIAL_PHONG, {0.1f, 0.1f, 0.1f}, NONE, {0.7f, 0.7f, 0.7f}, NONE, 40.0f, {0.0f, 0.0f, 0.0f}, 1.0f, {1.0f, 1.0f, 1.0f}, 0.0f},
    {MAT, EMBER_MATERIAL_MIXTURE, {0.5f, 0.4f, 0.3f}, NONE, {0.3f, 0.3f, 0.3f}, NONE, 15.0f, {0.0f, 0.0f, 0.0f}, 1.0f, {1.0f, 1.0f, 1.0f}, 0.0f},
    {MAT, EMBER_MATERIAL_DIFFUSE, {0.0f, 0.0f, 0.0f}, 0, {0.0f, 0.0f, 0.0f}, NONE, 1.0f, {0.0f, 0.0f, 0.0f}, 1.0f, {1.0f, 1.0f, 1.0f}, 0.0f},
    {MAT, EMBER_MATERIAL_CONDUCTOR, {0.0f, 0.0f, 0.0f}, NONE, {0.95f, 0.93f, 0.88f}, NONE, 1.0f, {0.0f, 0.0f, 0.0f}, 1.0f, {1.0f, 1.0f, 1.0f}, 0.0f},
    {MAT, EMBER_MATERIAL_CONDUCTOR, {0.0f, 0.0f, 0.0f}, NONE, {0.9f, 0.6f, 0.35f}, NONE, 1.0f, {0.0f, 0.0f, 0.0f}, 1.0f, {1.0f, 1.0f, 1.0f}, 0.2f},
    {MAT, EMBER_MATERIAL_DIELECTRIC, {0.0f, 0.0f, 0.0f}, NONE, {0.0f, 0.0f, 0.0f}, NONE, 1.0f, {0.0f, 0.0f, 0.0f}, 1.5f, {0.95f, 0.97f, 1.0f}, 0.0f},
    {MAT, EMBER_MATERIAL_DIELECTRIC, {0.0f, 0.0f, 0.0f}, NONE, {0.0f, 0.0f, 0.0f}, NONE, 1.0f, {0.0f, 0.0f, 0.0f}, 1.5f, {1.0f, 1.0f, 1.0f}, 0.15f},
    {MAT, EMBER_MATERIAL_PHONG, {0.0f, 0.0f, 0.0f}, 1, {0.0f, 0.0f, 0.0f}, 2, 30.0f, {0.0f, 0.0f, 0.0f}, 1.0f, {1.0f, 1.0f, 1.0f}, 0.0f},
};

/* Linear texels, each texture bottom row first. */
static const float TEXELS[NTEXELS][3] = {
    /* Texture 0: 4x4. */
    {0.8f, 0.78f, 0.74f},
    {0.25f, 0.25f, 0.3f},
    {0.8f, 0.78f, 0.74f},
    {0.25f, 0.25f, 0.3f},
    {0.25f, 0.25f, 0.3f},
    {0.8f, 0.78f, 0.74f},
    {0.25f, 0.25f, 0.3f},
    {0.8f, 0.78f, 0.74f},
    {0.8f, 0.78f, 0.74f},
    {0.25f, 0.25f, 0.3f},
    {0.8f, 0.78f, 0.74f},
    {0.25f, 0.25f, 0.3f},
    {0.25f, 0.25f, 0.3f},
    {0.8f, 0.78f, 0.74f},
    {0.25f, 0.25f, 0.3f},
    {0.7f, 0.2f, 0.15f},
    /* Texture 1: 4x4. */
    {0.1f, 0.1f, 0.5f},
    {0.2f, 0.1f, 0.45f},
    {0.3f, 0.15f, 0.4f},
    {0.4f, 0.2f, 0.35f},
    {0.1f, 0.3f, 0.4f},
    {0.2f, 0.35f, 0.35f},
    {0.35f, 0.35f, 0.3f},
    {0.5f, 0.4f, 0.25f},
    {0.1f, 0.5f, 0.3f},
    {0.25f, 0.55f, 0.25f},
    {0.45f, 0.55f, 0.2f},
    {0.65f, 0.55f, 0.15f},
    {0.1f, 0.7f, 0.2f},
    {0.3f, 0.7f, 0.15f},
    {0.55f, 0.7f, 0.1f},
    {0.8f, 0.7f, 0.05f},
    /* Texture 2: 2x2. */
    {0.6f, 0.6f, 0.6f},
    {0.2f, 0.2f, 0.2f},
    {0.4f, 0.3f, 0.2f},
    {0.05f, 0.05f, 0.05f},
};

/* width, height, first_texel, uv_scale, uv_offset. */
static const EmberTexture TEXTURES[NTEXTURES] = {
    {4, 4, 0, {2.0f, 2.0f}, {0.125f, 0.0f}},
    {4, 4, 16, {1.0f, 1.0f}, {0.0f, 0.0f}},
    {2, 2, 32, {1.0f, 1.0f}, {0.0f, 0.0f}},
};

/* struct_size, p, n, uv, material, key. */
static const EmberBakePoint POINTS[NPOINTS] = {
    {sizeof(EmberBakePoint), {0.0f, 0.0f, 0.7f}, {0.0f, 1.0f, 0.0f}, {0.5f, 0.15f}, 6, 0},
    {sizeof(EmberBakePoint), {0.0f, 1.0f, -1.0f}, {0.0f, 0.0f, 1.0f}, {0.0f, 0.0f}, 0, 1},
    {sizeof(EmberBakePoint), {-1.0f, 0.4f, 0.6f}, {1.0f, 0.0f, 0.0f}, {0.0f, 0.0f}, 1, 2},
    {sizeof(EmberBakePoint), {1.0f, 1.8f, -0.6f}, {-1.0f, 0.0f, 0.0f}, {0.0f, 0.0f}, 2, 3},
    {sizeof(EmberBakePoint), {0.6f, 2.0f, 0.6f}, {0.0f, -1.0f, 0.0f}, {0.0f, 0.0f}, 0, 4},
    {sizeof(EmberBakePoint), {0.4f, 1.2f, -0.4f}, {0.0f, 1.0f, 0.0f}, {0.0f, 0.0f}, 4, 5},
    {sizeof(EmberBakePoint), {-0.45f, 0.6f, 0.1f}, {0.0f, 1.0f, 0.0f}, {0.0f, 0.0f}, 5, 6},
    {sizeof(EmberBakePoint), {-1.0f, 0.0f, -1.0f}, {0.0f, 1.0f, 0.0f}, {0.0f, 1.0f}, 6, 7},
    {sizeof(EmberBakePoint), {-0.99f, 1.2f, -0.3f}, {1.0f, 0.0f, 0.0f}, {0.5f, 0.5f}, 7, 8},
    {sizeof(EmberBakePoint), {0.99f, 1.1f, 0.2f}, {-1.0f, 0.0f, 0.0f}, {0.5f, 0.5f}, 8, 9},
    {sizeof(EmberBakePoint), {0.175f, 0.45f, 0.45f}, {0.0f, 1.0f, 0.0f}, {0.5f, 0.5f}, 9, 10},
    {sizeof(EmberBakePoint), {0.175f, 0.2f, 0.65f}, {0.0f, 0.0f, 1.0f}, {0.5f, 0.5f}, 10, 11},
    {sizeof(EmberBakePoint), {0.5f, 1.6f, -0.99f}, {0.0f, 0.0f, 1.0f}, {0.5f, 0.5f}, 11, 12},
    {sizeof(EmberBakePoint), {0.6f, 0.0f, 0.4f}, {0.0f, 1.0f, 0.0f}, {0.8f, 0.3f}, 6, 13},
};

/* 0x656D626572: "ember", the command line's default seed. */
#define SEED 0x656D626572ull

static const EmberCamera CAMERA = {sizeof(EmberCamera), {0.0f, 1.0f, 3.4f}, {0.0f, 1.0f, 0.0f},
                                   {0.0f, 1.0f, 0.0f}, 40.0f, WIDTH, HEIGHT};

static float positions[NVERTICES][3];
static float normals[NVERTICES][3];
static float uvs[NVERTICES][2];
static uint32_t triangles[NTRIANGLES][3];
static uint32_t triangle_materials[NTRIANGLES];

/* A material as a program compiled against the version 1 header laid it out. */
typedef struct LegacyMaterial {
    uint32_t kind;
    float kd[3];
    float ks[3];
    float ns;
    float ke[3];
} LegacyMaterial;

#define CHECK(call)                                                                         \
    do {                                                                                    \
        int32_t status_ = (call);                                                           \
        if (status_ != EMBER_OK) {                                                          \
            fprintf(stderr, "cornell: %s failed with %d (line %d)\n", #call, status_,       \
                    __LINE__);                                                              \
            exit(1);                                                                        \
        }                                                                                   \
    } while (0)

#define EXPECT(call, code)                                                                  \
    do {                                                                                    \
        int32_t status_ = (call);                                                           \
        if (status_ != (code)) {                                                            \
            fprintf(stderr, "cornell: %s returned %d, expected %s\n", #call, status_, #code); \
            exit(1);                                                                        \
        }                                                                                   \
    } while (0)

typedef struct Job {
    const EmberScene *scene;
    const EmberSettings *settings;
    float *image; /* WIDTH * HEIGHT * 3: means, or own-sample sums when splats is set */
    uint32_t y0, y1;
    int64_t (*splats)[3]; /* NULL: ember_render_tile; else this thread's splat buffer */
    size_t splat_count;
    void *scratch; /* BDPT's subpaths, one per thread */
    size_t scratch_bytes;
    int32_t status;
} Job;

/* Renders rows y0 .. y1 in TILE x TILE tiles and copies each into the image. */
static void *render_rows(void *arg) {
    Job *job = arg;
    float tile[TILE * TILE * 3];
    job->status = EMBER_OK;
    for (uint32_t ty = job->y0; ty < job->y1; ty += TILE) {
        for (uint32_t tx = 0; tx < WIDTH; tx += TILE) {
            uint32_t w = WIDTH - tx < TILE ? WIDTH - tx : TILE;
            uint32_t h = job->y1 - ty < TILE ? job->y1 - ty : TILE;
            int32_t s = job->splats
                            ? ember_render_tile_splats(job->scene, &CAMERA, job->settings, tx,
                                                       ty, w, h, tile, job->splats,
                                                       job->splat_count, job->scratch,
                                                       job->scratch_bytes)
                            : ember_render_tile(job->scene, &CAMERA, job->settings, tx, ty, w,
                                                h, tile);
            if (s != EMBER_OK) {
                job->status = s;
                return NULL;
            }
            for (uint32_t y = 0; y < h; y++) {
                memcpy(&job->image[((ty + y) * WIDTH + tx) * 3], &tile[y * w * 3],
                       w * 3 * sizeof(float));
            }
        }
    }
    return NULL;
}

/* The rendering threads' stacks: EMBER_STACK_BYTES each, filled with PAINT before a thread
 * starts, so that the deepest byte it overwrote shows how much stack it used. */
#define PAINT 0xA5
#define NTHREADS 2
static unsigned char *stacks[NTHREADS];
static unsigned char *stack_blocks[NTHREADS]; /* a guard page, then the stack */
static size_t page;
static size_t stack_peak; /* the most any rendering thread used */

/* Bytes of `stack` (EMBER_STACK_BYTES, growing down) that a thread overwrote. */
static size_t stack_used(const unsigned char *stack) {
    size_t untouched = 0;
    while (untouched < EMBER_STACK_BYTES && stack[untouched] == PAINT) untouched++;
    return EMBER_STACK_BYTES - untouched;
}

/* Runs the jobs on NTHREADS threads with painted stacks of EMBER_STACK_BYTES. */
static void run_jobs(Job jobs[NTHREADS]) {
    pthread_t threads[NTHREADS];
    for (int t = 0; t < NTHREADS; t++) {
        pthread_attr_t attr;
        memset(stacks[t], PAINT, EMBER_STACK_BYTES);
        if (pthread_attr_init(&attr) != 0 ||
            pthread_attr_setstack(&attr, stacks[t], EMBER_STACK_BYTES) != 0 ||
            pthread_create(&threads[t], &attr, render_rows, &jobs[t]) != 0) {
            fprintf(stderr, "cornell: cannot start a thread on a %u-byte stack\n",
                    (unsigned)EMBER_STACK_BYTES);
            exit(1);
        }
        pthread_attr_destroy(&attr);
    }
    for (int t = 0; t < NTHREADS; t++) {
        pthread_join(threads[t], NULL);
        size_t used = stack_used(stacks[t]);
        if (used > stack_peak) stack_peak = used;
        if (2 * used > EMBER_STACK_BYTES) {
            fprintf(stderr, "cornell: a rendering thread used %zu of its %u stack bytes\n",
                    used, (unsigned)EMBER_STACK_BYTES);
            exit(1);
        }
    }
    for (int t = 0; t < NTHREADS; t++) {
        if (jobs[t].status != EMBER_OK) {
            fprintf(stderr, "cornell: thread %d failed with %d\n", t, (int)jobs[t].status);
            exit(1);
        }
    }
}

/* The splatting integrators, as tests/determinism renders them (SPLAT_INTEGRATORS). */
#define NSPLAT 3
static const uint32_t SPLAT_INTEGRATORS[NSPLAT] = {
    EMBER_INTEGRATOR_LIGHT_TRACING, EMBER_INTEGRATOR_BDPT, EMBER_INTEGRATOR_BDPT_BALANCE};

/* 64-bit FNV-1a over the little-endian bytes of each float (tests/determinism's hash). */
static uint64_t fnv1a(uint64_t h, const float *values, size_t n) {
    for (size_t i = 0; i < n; i++) {
        uint32_t bits;
        memcpy(&bits, &values[i], sizeof bits);
        for (int b = 0; b < 4; b++) {
            h ^= (bits >> (8 * b)) & 0xffu;
            h *= 0x100000001b3ull;
        }
    }
    return h;
}

static void write_all(FILE *f, const void *data, size_t bytes) {
    if (bytes > 0 && fwrite(data, 1, bytes, f) != bytes) {
        fprintf(stderr, "cornell: write failed\n");
        exit(1);
    }
}

static void write_u32(FILE *f, uint32_t v) { write_all(f, &v, sizeof v); }

int main(int argc, char **argv) {
    /* The library must implement the header this program was compiled with. */
    if (ember_abi_version() != EMBER_ABI_VERSION) {
        fprintf(stderr, "cornell: ember ABI %u, header %u\n", (unsigned)ember_abi_version(),
                (unsigned)EMBER_ABI_VERSION);
        return 1;
    }
    for (uint32_t q = 0; q < NQUADS; q++) {
        for (uint32_t c = 0; c < 4; c++) {
            memcpy(positions[4 * q + c], QUADS[q].corners[c], sizeof positions[0]);
            memcpy(normals[4 * q + c], QUADS[q].normal, sizeof normals[0]);
            memcpy(uvs[4 * q + c], QUAD_UVS[c], sizeof uvs[0]);
        }
        uint32_t v = 4 * q;
        uint32_t t0[3] = {v, v + 1, v + 2}, t1[3] = {v, v + 2, v + 3};
        memcpy(triangles[2 * q], t0, sizeof t0);
        memcpy(triangles[2 * q + 1], t1, sizeof t1);
        triangle_materials[2 * q] = triangle_materials[2 * q + 1] = QUADS[q].material;
    }

    EmberScene scene;
    memset(&scene, 0, sizeof scene);
    scene.struct_size = sizeof scene;
    scene.positions = (const float(*)[3])positions;
    scene.normals = (const float(*)[3])normals;
    scene.vertex_count = NVERTICES;
    scene.uvs = (const float(*)[2])uvs;
    scene.triangles = (const uint32_t(*)[3])triangles;
    scene.triangle_materials = triangle_materials;
    scene.triangle_count = NTRIANGLES;
    scene.materials = MATERIALS;
    scene.material_count = NMATERIALS;
    scene.textures = TEXTURES;
    scene.texture_count = NTEXTURES;
    scene.texels = TEXELS;
    scene.texel_count = NTEXELS;

    /* The BVH, in buffers sized by the query. */
    uint32_t node_capacity = 0, index_capacity = 0, node_count = 0;
    CHECK(ember_bvh_capacity(NTRIANGLES, &node_capacity, &index_capacity));
    EmberBvhNode *nodes = calloc(node_capacity, sizeof *nodes);
    uint32_t *indices = calloc(index_capacity, sizeof *indices);
    if (!nodes || !indices) return 1;
    EXPECT(ember_build_bvh(&scene, nodes, node_capacity - 1, indices, index_capacity, NULL),
           EMBER_ERROR_SIZE);
    CHECK(ember_build_bvh(&scene, nodes, node_capacity, indices, index_capacity, &node_count));

    /* The emitter table: ask for its size, then fill it. */
    uint32_t emitter_count = 0;
    EXPECT(ember_build_emitters(&scene, NULL, NULL, 0, &emitter_count), EMBER_ERROR_SIZE);
    uint32_t *emitter_triangles = calloc(emitter_count, sizeof *emitter_triangles);
    float *emitter_cdf = calloc(emitter_count, sizeof *emitter_cdf);
    if (!emitter_triangles || !emitter_cdf) return 1;
    CHECK(ember_build_emitters(&scene, emitter_triangles, emitter_cdf, emitter_count,
                               &emitter_count));

    scene.emitter_triangles = emitter_triangles;
    scene.emitter_cdf = emitter_cdf;
    scene.emitter_count = emitter_count;
    scene.bvh_nodes = nodes;
    scene.bvh_node_count = node_count;
    scene.bvh_indices = indices;
    CHECK(ember_scene_check(&scene));
    /* The scene as traced with the binary BVH; `scene` gets the acceleration structure. */
    EmberScene binary_scene = scene;

    /* The acceleration structure, in buffers sized by the query and aligned as it requires
     * (aligned_alloc wants a multiple of the alignment; one block more for the misaligned
     * attempt below). The scratch is needed during the build only. */
    size_t accel_capacity = 0, accel_scratch_bytes = 0, accel_used = 0;
    CHECK(ember_accel_capacity(NTRIANGLES, &accel_capacity, &accel_scratch_bytes));
    size_t accel_block = (accel_capacity / EMBER_ACCEL_ALIGN + 2) * EMBER_ACCEL_ALIGN;
    unsigned char *accel = aligned_alloc(EMBER_ACCEL_ALIGN, accel_block);
    void *accel_scratch = aligned_alloc(
        EMBER_ACCEL_ALIGN, (accel_scratch_bytes / EMBER_ACCEL_ALIGN + 1) * EMBER_ACCEL_ALIGN);
    if (!accel || !accel_scratch) return 1;
    EXPECT(ember_build_accel(&scene, accel, accel_capacity - 1, accel_scratch,
                             accel_scratch_bytes, NULL),
           EMBER_ERROR_SIZE);
    EXPECT(ember_build_accel(&scene, accel + 4, accel_capacity, accel_scratch,
                             accel_scratch_bytes, NULL),
           EMBER_ERROR_SIZE);
    EXPECT(ember_build_accel(&scene, accel, accel_capacity, accel_scratch,
                             accel_scratch_bytes - 1, NULL),
           EMBER_ERROR_SIZE);
    CHECK(ember_build_accel(&scene, accel, accel_capacity, accel_scratch, accel_scratch_bytes,
                            &accel_used));
    free(accel_scratch);
    if (accel_used == 0 || accel_used > accel_capacity) return 1;
    scene.accel = accel;
    scene.accel_bytes = accel_used;
    CHECK(ember_scene_check(&scene));

    for (int t = 0; t < NTHREADS; t++) {
        /* Below each stack a page that faults when touched: a thread that outgrows its stack
         * crashes instead of writing over other memory. */
        long ps = sysconf(_SC_PAGESIZE);
        page = ps > 0 ? (size_t)ps : 4096;
        stack_blocks[t] = aligned_alloc(page, page + EMBER_STACK_BYTES);
        if (!stack_blocks[t] || mprotect(stack_blocks[t], page, PROT_NONE) != 0) return 1;
        stacks[t] = stack_blocks[t] + page;
    }

    /* Three renders, each by two threads. */
    static float images[3][WIDTH * HEIGHT * 3];
    /* EMBER_SAMPLER_DEFAULT: each integrator's own, as tests/determinism renders. */
    EmberSettings settings = {sizeof(EmberSettings), EMBER_INTEGRATOR_PATH_IMPLICIT, -1, 3, 0.9f,
                              4, EMBER_BAKE_MIS, SEED, EMBER_SAMPLER_DEFAULT};
    const uint32_t integrators[3] = {EMBER_INTEGRATOR_PATH_IMPLICIT,
                                     EMBER_INTEGRATOR_PATH_EXPLICIT, EMBER_INTEGRATOR_PATH_MIS};
    for (int k = 0; k < 3; k++) {
        settings.integrator = integrators[k];
        Job jobs[NTHREADS] = {{&scene, &settings, images[k], 0, HEIGHT / 2, NULL, 0, NULL, 0, 0},
                              {&scene, &settings, images[k], HEIGHT / 2, HEIGHT, NULL, 0, NULL,
                               0, 0}};
        run_jobs(jobs);
    }

    /* The splatting renders: the same two threads and tiles, each thread with its own splat
     * buffer (zeroed) and scratch, the buffers merged after the join, the image resolved. */
    size_t splat_count = 0, splat_bytes = 0;
    CHECK(ember_splat_buffer_size(WIDTH, HEIGHT, &splat_count, &splat_bytes));
    if (splat_count != WIDTH * HEIGHT || splat_bytes != splat_count * sizeof(int64_t[3])) {
        fprintf(stderr, "cornell: splat buffer of %zu entries, %zu bytes\n", splat_count,
                splat_bytes);
        return 1;
    }
    size_t scratch_bytes = 0, scratch_align = 0;
    CHECK(ember_render_scratch_size(EMBER_INTEGRATOR_BDPT, &scratch_bytes, &scratch_align));
    static float splat_sums[NSPLAT][WIDTH * HEIGHT * 3];
    static int64_t merged[NSPLAT][WIDTH * HEIGHT][3];
    static float splat_images[NSPLAT][WIDTH * HEIGHT * 3];
    int64_t (*thread_splats[NTHREADS])[3];
    void *scratches[NTHREADS];
    for (int t = 0; t < NTHREADS; t++) {
        thread_splats[t] = malloc(splat_bytes);
        /* malloc memory is aligned for any object, scratch_align (a power of two) included. */
        scratches[t] = malloc(scratch_bytes);
        if (!thread_splats[t] || !scratches[t] || (uintptr_t)scratches[t] % scratch_align) {
            return 1;
        }
    }
    for (int k = 0; k < NSPLAT; k++) {
        EmberSettings s = settings;
        s.integrator = SPLAT_INTEGRATORS[k];
        Job jobs[NTHREADS];
        for (int t = 0; t < NTHREADS; t++) {
            memset(thread_splats[t], 0, splat_bytes);
            Job job = {&scene, &s, splat_sums[k], t * HEIGHT / NTHREADS,
                       (t + 1) * HEIGHT / NTHREADS, thread_splats[t], splat_count, scratches[t],
                       scratch_bytes, 0};
            jobs[t] = job;
        }
        run_jobs(jobs);
        /* Merge in the other order than the threads were started in: it does not matter. */
        memset(merged[k], 0, splat_bytes);
        for (int t = NTHREADS - 1; t >= 0; t--) {
            CHECK(ember_splat_merge(merged[k], (const int64_t(*)[3])thread_splats[t],
                                    splat_count));
        }
        CHECK(ember_splat_resolve(splat_sums[k], (const int64_t(*)[3])merged[k], splat_count,
                                  s.spp, splat_images[k]));
    }

    /* Independent of the split: BDPT as one call for the whole film on this thread, into one
     * buffer, gives the same sums, splats and image; and a path tracer through the splat entry,
     * resolved with no splats, gives ember_render_tile's means. */
    {
        static float sums[WIDTH * HEIGHT * 3], image[WIDTH * HEIGHT * 3];
        static int64_t one[WIDTH * HEIGHT][3];
        EmberSettings s = settings;
        s.integrator = SPLAT_INTEGRATORS[1];
        memset(one, 0, sizeof one);
        CHECK(ember_render_tile_splats(&scene, &CAMERA, &s, 0, 0, WIDTH, HEIGHT, sums, one,
                                       splat_count, scratches[0], scratch_bytes));
        CHECK(ember_splat_resolve(sums, (const int64_t(*)[3])one, splat_count, s.spp, sums));
        if (memcmp(one, merged[1], sizeof one) != 0 ||
            memcmp(sums, splat_images[1], sizeof sums) != 0) {
            fprintf(stderr, "cornell: one-call BDPT differs from the two-thread tiled render\n");
            return 1;
        }
        s.integrator = EMBER_INTEGRATOR_PATH_MIS;
        memset(one, 0, sizeof one);
        CHECK(ember_render_tile_splats(&scene, &CAMERA, &s, 0, 0, WIDTH, HEIGHT, sums, NULL, 0,
                                       NULL, 0));
        CHECK(ember_splat_resolve(sums, (const int64_t(*)[3])one, splat_count, s.spp, image));
        if (memcmp(image, images[2], sizeof image) != 0) {
            fprintf(stderr, "cornell: resolved MIS sums differ from ember_render_tile\n");
            return 1;
        }
    }

    /* The bake, both estimators; the points in two batches (keys make batching irrelevant). */
    static float bakes[2][NPOINTS * 3];
    EmberSettings bake = {sizeof(EmberSettings), EMBER_INTEGRATOR_PATH_MIS, 5, 5, 0.95f, 16,
                          EMBER_BAKE_MIS, SEED, EMBER_SAMPLER_DEFAULT};
    const uint32_t estimators[2] = {EMBER_BAKE_MIS, EMBER_BAKE_EXPLICIT};
    for (int k = 0; k < 2; k++) {
        bake.bake_estimator = estimators[k];
        CHECK(ember_bake_vertices(&scene, &bake, POINTS, 3, bakes[k]));
        CHECK(ember_bake_vertices(&scene, &bake, POINTS + 3, NPOINTS - 3, bakes[k] + 9));
    }

    /* The binary BVH traces the same closest hits and shadow rays: every path tracer's image
     * (one call for the whole film) and the bakes are the same bits. */
    {
        static float image[WIDTH * HEIGHT * 3], baked[NPOINTS * 3];
        EmberSettings s = settings;
        for (int k = 0; k < 3; k++) {
            s.integrator = integrators[k];
            CHECK(ember_render_tile(&binary_scene, &CAMERA, &s, 0, 0, WIDTH, HEIGHT, image));
            if (memcmp(image, images[k], sizeof image) != 0) {
                fprintf(stderr, "cornell: integrator %u differs with the binary BVH\n",
                        (unsigned)integrators[k]);
                return 1;
            }
        }
        for (int k = 0; k < 2; k++) {
            bake.bake_estimator = estimators[k];
            CHECK(ember_bake_vertices(&binary_scene, &bake, POINTS, NPOINTS, baked));
            if (memcmp(baked, bakes[k], sizeof baked) != 0) {
                fprintf(stderr, "cornell: bake %d differs with the binary BVH\n", k);
                return 1;
            }
        }
    }

    /* Bad input gets error codes, never a crash. */
    float px[3];
    EXPECT(ember_render_tile(NULL, &CAMERA, &settings, 0, 0, 1, 1, px), EMBER_ERROR_NULL_POINTER);
    EXPECT(ember_render_tile(&scene, &CAMERA, &settings, WIDTH - 1, 0, 2, 1, px),
           EMBER_ERROR_INVALID_ARGUMENT);
    EXPECT(ember_render_tile(&scene, &CAMERA, &settings, 0, 0, 1, 1, NULL),
           EMBER_ERROR_NULL_POINTER);
    EmberSettings bad_settings = settings;
    bad_settings.integrator = 7;
    EXPECT(ember_render_tile(&scene, &CAMERA, &bad_settings, 0, 0, 1, 1, px),
           EMBER_ERROR_INVALID_ARGUMENT);
    bad_settings = settings;
    bad_settings.sampler = EMBER_SAMPLER_ZSOBOL + 1;
    EXPECT(ember_render_tile(&scene, &CAMERA, &bad_settings, 0, 0, 1, 1, px),
           EMBER_ERROR_INVALID_ARGUMENT);
    /* The splatting integrators: not through ember_render_tile, and only with their buffers. */
    EmberSettings bdpt = settings;
    bdpt.integrator = EMBER_INTEGRATOR_BDPT;
    EXPECT(ember_render_tile(&scene, &CAMERA, &bdpt, 0, 0, 1, 1, px),
           EMBER_ERROR_INVALID_ARGUMENT);
    EXPECT(ember_render_tile_splats(&scene, &CAMERA, &bdpt, 0, 0, 1, 1, px, NULL, 0,
                                    scratches[0], scratch_bytes),
           EMBER_ERROR_NULL_POINTER);
    EXPECT(ember_render_tile_splats(&scene, &CAMERA, &bdpt, 0, 0, 1, 1, px, thread_splats[0],
                                    splat_count - 1, scratches[0], scratch_bytes),
           EMBER_ERROR_SIZE);
    EXPECT(ember_render_tile_splats(&scene, &CAMERA, &bdpt, 0, 0, 1, 1, px, thread_splats[0],
                                    splat_count, NULL, 0),
           EMBER_ERROR_NULL_POINTER);
    EXPECT(ember_render_tile_splats(&scene, &CAMERA, &bdpt, 0, 0, 1, 1, px, thread_splats[0],
                                    splat_count, scratches[0], scratch_bytes - 1),
           EMBER_ERROR_SIZE);
    bdpt.max_depth = EMBER_BDPT_MAX_DEPTH + 1;
    EXPECT(ember_render_tile_splats(&scene, &CAMERA, &bdpt, 0, 0, 1, 1, px, thread_splats[0],
                                    splat_count, scratches[0], scratch_bytes),
           EMBER_ERROR_INVALID_ARGUMENT);
    EXPECT(ember_splat_merge(thread_splats[0], (const int64_t(*)[3])thread_splats[0],
                             splat_count),
           EMBER_ERROR_INVALID_ARGUMENT);
    EXPECT(ember_splat_resolve(splat_sums[0], (const int64_t(*)[3])merged[0], splat_count, 0,
                               px),
           EMBER_ERROR_INVALID_ARGUMENT);
    EXPECT(ember_splat_buffer_size(0, HEIGHT, NULL, NULL), EMBER_ERROR_INVALID_ARGUMENT);
    EXPECT(ember_render_scratch_size(7, NULL, NULL), EMBER_ERROR_INVALID_ARGUMENT);
    EmberScene bad = scene;
    bad.material_count = 3; /* triangles refer to materials 3 to 11 */
    EXPECT(ember_render_tile(&bad, &CAMERA, &settings, 0, 0, 1, 1, px), EMBER_ERROR_INVALID_SCENE);
    bad = binary_scene;
    bad.bvh_node_count = 1; /* the root's children are missing */
    EXPECT(ember_scene_check(&bad), EMBER_ERROR_INVALID_SCENE);
    bad = scene; /* with an acceleration structure the binary BVH is not read */
    bad.bvh_node_count = 1;
    CHECK(ember_scene_check(&bad));
    bad = scene;
    bad.accel_bytes = accel_used - 1; /* truncated */
    EXPECT(ember_render_tile(&bad, &CAMERA, &settings, 0, 0, 1, 1, px), EMBER_ERROR_SIZE);
    bad = scene;
    bad.accel = accel + 4; /* misaligned */
    EXPECT(ember_scene_check(&bad), EMBER_ERROR_SIZE);
    {
        /* Damaged copies: another magic; a leaf lane of the root pointing past the order. */
        unsigned char *copy = aligned_alloc(EMBER_ACCEL_ALIGN, accel_block);
        if (!copy) return 1;
        bad = scene;
        bad.accel = copy;
        memcpy(copy, accel, accel_used);
        CHECK(ember_scene_check(&bad));
        copy[0] ^= 1;
        EXPECT(ember_scene_check(&bad), EMBER_ERROR_INVALID_SCENE);
        EXPECT(ember_bake_vertices(&bad, &bake, POINTS, 1, px), EMBER_ERROR_INVALID_SCENE);
        memcpy(copy, accel, accel_used);
        /* The root's child indices start 24 lanes of floats into the node at byte 64. */
        uint32_t width, past = 0xffffffffu;
        memcpy(&width, copy + 8, sizeof width);
        for (uint32_t lane = 0; lane < width; lane++) {
            memcpy(copy + 64 + 24 * width + 4 * lane, &past, sizeof past);
        }
        EXPECT(ember_scene_check(&bad), EMBER_ERROR_INVALID_SCENE);
        free(copy);
    }
    bad = scene;
    bad.emitter_cdf = NULL;
    EXPECT(ember_scene_check(&bad), EMBER_ERROR_NULL_POINTER);
    bad = scene;
    bad.uvs = NULL; /* materials 6 and 11 are textured */
    EXPECT(ember_scene_check(&bad), EMBER_ERROR_NULL_POINTER);
    bad = scene;
    bad.texture_count = 2; /* material 11 reads texture 2 */
    EXPECT(ember_scene_check(&bad), EMBER_ERROR_INVALID_SCENE);
    bad = scene;
    bad.texel_count = NTEXELS - 1; /* texture 2 ends at the last texel */
    EXPECT(ember_scene_check(&bad), EMBER_ERROR_INVALID_SCENE);
    EmberMaterial bad_materials[NMATERIALS];
    memcpy(bad_materials, MATERIALS, sizeof MATERIALS);
    bad_materials[9].ior = 0.0f;
    bad = scene;
    bad.materials = bad_materials;
    EXPECT(ember_scene_check(&bad), EMBER_ERROR_INVALID_SCENE);
    bad_materials[9] = MATERIALS[9];
    bad_materials[8].alpha = -0.2f;
    EXPECT(ember_scene_check(&bad), EMBER_ERROR_INVALID_SCENE);
    EmberBakePoint bad_point = POINTS[0];
    bad_point.material = NMATERIALS;
    EXPECT(ember_bake_vertices(&scene, &bake, &bad_point, 1, px), EMBER_ERROR_INVALID_ARGUMENT);

    /* Records of another ABI version are refused, not misread: version 1 materials (their
     * first field is the kind), a zeroed size, a record one field larger. */
    LegacyMaterial legacy[NMATERIALS];
    for (int i = 0; i < NMATERIALS; i++) {
        legacy[i].kind = MATERIALS[i].kind < 3 ? MATERIALS[i].kind : 0;
        memcpy(legacy[i].kd, MATERIALS[i].kd, sizeof legacy[i].kd);
        memcpy(legacy[i].ks, MATERIALS[i].ks, sizeof legacy[i].ks);
        legacy[i].ns = MATERIALS[i].ns;
        memcpy(legacy[i].ke, MATERIALS[i].ke, sizeof legacy[i].ke);
    }
    bad = scene;
    bad.materials = (const EmberMaterial *)(const void *)legacy;
    EXPECT(ember_scene_check(&bad), EMBER_ERROR_ABI);
    EXPECT(ember_render_tile(&bad, &CAMERA, &settings, 0, 0, 1, 1, px), EMBER_ERROR_ABI);
    bad = scene;
    bad.struct_size = 0;
    EXPECT(ember_scene_check(&bad), EMBER_ERROR_ABI);
    EXPECT(ember_build_emitters(&bad, NULL, NULL, 0, NULL), EMBER_ERROR_ABI);
    bad_settings = settings;
    bad_settings.struct_size = sizeof(EmberSettings) + 8;
    EXPECT(ember_render_tile(&scene, &CAMERA, &bad_settings, 0, 0, 1, 1, px), EMBER_ERROR_ABI);
    EmberCamera bad_camera = CAMERA;
    bad_camera.struct_size = 0;
    EXPECT(ember_render_tile(&scene, &bad_camera, &settings, 0, 0, 1, 1, px), EMBER_ERROR_ABI);
    bad_point = POINTS[0];
    bad_point.struct_size = 0;
    EXPECT(ember_bake_vertices(&scene, &bake, &bad_point, 1, px), EMBER_ERROR_ABI);

    uint64_t render_hash = 0xcbf29ce484222325ull;
    for (int k = 0; k < 3; k++) render_hash = fnv1a(render_hash, images[k], WIDTH * HEIGHT * 3);
    uint64_t bake_hash = 0xcbf29ce484222325ull;
    for (int k = 0; k < 2; k++) bake_hash = fnv1a(bake_hash, bakes[k], NPOINTS * 3);
    uint64_t splat_hash = 0xcbf29ce484222325ull;
    for (int k = 0; k < NSPLAT; k++) {
        splat_hash = fnv1a(splat_hash, splat_images[k], WIDTH * HEIGHT * 3);
    }
    printf("render %016llx\nbake %016llx\nsplat %016llx\n", (unsigned long long)render_hash,
           (unsigned long long)bake_hash, (unsigned long long)splat_hash);
    fprintf(stderr, "stack %zu\n", stack_peak);

    if (argc > 1) {
        FILE *f = fopen(argv[1], "wb");
        if (!f) {
            perror(argv[1]);
            return 1;
        }
        write_u32(f, NVERTICES);
        write_all(f, positions, sizeof positions);
        write_all(f, normals, sizeof normals);
        write_all(f, uvs, sizeof uvs);
        write_u32(f, NTRIANGLES);
        write_all(f, triangles, sizeof triangles);
        write_all(f, triangle_materials, sizeof triangle_materials);
        write_u32(f, NTEXTURES);
        write_all(f, TEXTURES, sizeof TEXTURES);
        write_u32(f, NTEXELS);
        write_all(f, TEXELS, sizeof TEXELS);
        write_u32(f, emitter_count);
        write_all(f, emitter_triangles, emitter_count * sizeof *emitter_triangles);
        write_all(f, emitter_cdf, emitter_count * sizeof *emitter_cdf);
        write_u32(f, node_count);
        write_all(f, nodes, node_count * sizeof *nodes);
        write_all(f, indices, NTRIANGLES * sizeof *indices);
        write_u32(f, (uint32_t)accel_used);
        write_all(f, accel, accel_used);
        write_u32(f, WIDTH);
        write_u32(f, HEIGHT);
        write_all(f, images, sizeof images);
        write_u32(f, NPOINTS);
        write_all(f, bakes, sizeof bakes);
        write_u32(f, NSPLAT);
        write_all(f, splat_sums, sizeof splat_sums);
        write_all(f, merged, sizeof merged);
        write_all(f, splat_images, sizeof splat_images);
        write_u32(f, (uint32_t)stack_peak);
        if (fclose(f) != 0) {
            perror(argv[1]);
            return 1;
        }
    }
    free(nodes);
    free(indices);
    free(accel);
    free(emitter_triangles);
    free(emitter_cdf);
    for (int t = 0; t < NTHREADS; t++) {
        free(thread_splats[t]);
        free(scratches[t]);
        mprotect(stack_blocks[t], page, PROT_READ | PROT_WRITE);
        free(stack_blocks[t]);
    }
    return 0;
}
