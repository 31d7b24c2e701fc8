/* Drives libplugflow_dem_native through plugflow_dem.h alone, as a C user would: builds the
 * scene given as JSON in argv[1], advances argv[2] steps in chunks with a fluid force,
 * prints every grain's id and position as raw IEEE bits (so the Rust side compares bit for
 * bit), and exercises the error paths. Exit code 0 only when every check holds. */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "plugflow_dem.h"

#define CHECK(cond, ...)                                                                     \
    do {                                                                                     \
        if (!(cond)) {                                                                       \
            fprintf(stderr, __VA_ARGS__);                                                    \
            fprintf(stderr, "\n");                                                           \
            return 1;                                                                        \
        }                                                                                    \
    } while (0)

static char *slurp(const char *path, size_t *len) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *buf = malloc((size_t)n + 1);
    if (fread(buf, 1, (size_t)n, f) != (size_t)n) { fclose(f); free(buf); return NULL; }
    fclose(f);
    buf[n] = 0;
    *len = (size_t)n;
    return buf;
}

int main(int argc, char **argv) {
    CHECK(argc == 3, "usage: abi_check scene.json steps");
    CHECK(pf_dem_abi_version() >> 16 == PF_DEM_ABI_MAJOR, "ABI major differs");
    char err[512];

    /* A refused scene: status, no handle, and a message naming the field. */
    const char *bad = "{\"schema_version\": 1, \"name\": \"x\"}";
    pf_dem *dem = (pf_dem *)1;
    CHECK(pf_dem_create(bad, strlen(bad), &dem) == PF_ERR_SCENE, "bad scene accepted");
    CHECK(dem == NULL, "handle set on failure");
    size_t n_err = pf_dem_last_error(NULL, err, sizeof err);
    CHECK(n_err > 0 && strstr(err, "duration") != NULL, "create error does not name the field: %s", err);

    size_t len = 0;
    char *json = slurp(argv[1], &len);
    CHECK(json != NULL, "cannot read %s", argv[1]);
    CHECK(pf_dem_create(json, len, &dem) == PF_OK, "create failed");
    pf_dem_info info;
    CHECK(pf_dem_info_get(dem, &info) == PF_OK, "info failed");
    CHECK(strcmp(info.name, "native") == 0, "engine name %s", info.name);
    CHECK(pf_dem_info_get(dem, NULL) == PF_ERR_NULL, "NULL info accepted");

    long steps = atol(argv[2]);
    for (long done = 0; done < steps; done += 100) {
        CHECK(pf_dem_advance(dem, 100) == PF_OK, "advance failed");
        CHECK(pf_dem_info_get(dem, &info) == PF_OK, "info failed");
        size_t n = (size_t)info.particle_count;
        double *f = calloc(3 * n + 1, sizeof(double));
        for (size_t i = 0; i < n; i++) f[3 * i + 2] = 1e-6; /* a small upward fluid force */
        CHECK(pf_dem_set_fluid_forces(dem, n, f) == PF_OK, "set forces failed");
        free(f);
        double removed = -1.0;
        CHECK(pf_dem_remove_past_outlet(dem, &removed) == PF_OK && removed >= 0.0, "remove failed");
    }
    CHECK(pf_dem_info_get(dem, &info) == PF_OK, "info failed");
    size_t n = (size_t)info.particle_count;
    CHECK(n > 0, "no grains");
    uint64_t *id = malloc(n * sizeof *id);
    double *x = malloc(3 * n * sizeof *x);
    CHECK(pf_dem_read_particles(dem, n - 1, id, x, NULL, NULL, NULL, NULL) == PF_ERR_BUFFER_TOO_SMALL,
          "short buffer accepted");
    CHECK(pf_dem_last_error(dem, err, sizeof err) > 0, "no message for the short buffer");
    CHECK(pf_dem_read_particles(dem, n, id, x, NULL, NULL, NULL, NULL) == PF_OK, "read failed");
    /* A force array of the wrong length is refused with a reason. */
    double one[3] = {0, 0, 0};
    CHECK(pf_dem_set_fluid_forces(dem, 1, one) == PF_ERR_INVALID_ARGUMENT || n == 1,
          "wrong force count accepted");
    double wf[3 * 16];
    CHECK(info.wall_count <= 16, "too many walls");
    CHECK(pf_dem_read_wall_forces(dem, 16, wf) == PF_OK, "wall forces failed");
    char wname[64];
    CHECK(info.wall_count == 0 || pf_dem_wall_name(dem, 0, wname, sizeof wname) == PF_OK, "wall name");
    pf_dem_flow flow;
    CHECK(pf_dem_flow_get(dem, &flow) == PF_OK, "flow failed");
    printf("steps %" PRIu64 " grains %zu fed %" PRIu64 "\n", info.step_count, n, flow.fed_count);
    for (size_t i = 0; i < n; i++) {
        uint64_t b[3];
        memcpy(b, &x[3 * i], sizeof b);
        printf("%" PRIu64 " %016" PRIx64 " %016" PRIx64 " %016" PRIx64 "\n", id[i], b[0], b[1], b[2]);
    }
    pf_dem_destroy(dem);
    pf_dem_destroy(NULL);
    free(id);
    free(x);
    free(json);
    return 0;
}
