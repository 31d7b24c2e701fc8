/* plugflow DEM ABI: the one C interface every external DEM engine implements so that
 * plugflow's gas and coupling layer can drive it (bindings/native, bindings/liggghts,
 * bindings/yade). Licence: MIT OR Apache-2.0.
 *
 * Conventions
 *  - Units SI. Vectors are interleaved x, y, z triples of doubles (3 n values for n grains).
 *  - Grain order: the order of the last pf_dem_read_particles; it changes only in
 *    pf_dem_advance, pf_dem_insert and pf_dem_remove_past_outlet. Per-grain inputs
 *    (fluid forces) are given in that order.
 *  - Every call returns a pf_status; on failure pf_dem_last_error tells why. A call never
 *    ends the process and never lets an exception or a panic cross this boundary.
 *  - pf_dem_abi_version() == PF_DEM_ABI_MAJOR << 16 | PF_DEM_ABI_MINOR. A loader refuses a
 *    library with another major; minors only add optional calls (a loader binds optional
 *    calls only when the library exports them).
 *  - Optional calls: pf_dem_set_implicit_drag, pf_dem_flow_get, pf_dem_check (since 1.1),
 *    pf_dem_keep_log (1.2), pf_dem_save_state and pf_dem_restore_state (1.3),
 *    pf_dem_ranks and pf_dem_all_reduce (1.4).
 *  - Several processes (ABI 1.4): an engine run under MPI (one plugflow process per rank,
 *    one engine instance over all of them) reports its rank and rank count with
 *    pf_dem_ranks; every per-grain call then concerns the grains this rank owns, and
 *    pf_dem_all_reduce sums (or takes the maximum of) a buffer over all ranks on the
 *    engine's own communicator, so the caller needs no MPI of its own. Every rank calls
 *    pf_dem_advance, pf_dem_insert, pf_dem_remove_past_outlet, pf_dem_all_reduce,
 *    pf_dem_save_state and pf_dem_restore_state in the same order (they are collective);
 *    an engine that fails in one of them on one rank fails on every rank with that
 *    rank's message. An engine without these calls is one process (rank 0 of 1).
 */
#ifndef PLUGFLOW_DEM_H
#define PLUGFLOW_DEM_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define PF_DEM_ABI_MAJOR 1
#define PF_DEM_ABI_MINOR 4

/* Status codes (fixed numbers; never renumbered). */
#define PF_OK 0
#define PF_ERR_NULL 1             /* a required pointer or the handle is NULL */
#define PF_ERR_INVALID_ARGUMENT 2 /* an argument does not fit the engine's state */
#define PF_ERR_SCENE 3            /* the scene cannot be built (field and reason in last_error) */
#define PF_ERR_NON_FINITE 4       /* NaN or blow-up: step and grain in last_error */
#define PF_ERR_ENGINE 5           /* the engine failed (its message in last_error) */
#define PF_ERR_BUFFER_TOO_SMALL 6 /* capacity below the count; nothing written */
#define PF_ERR_PANIC 7            /* an internal error was caught at the boundary */
#define PF_ERR_UNSUPPORTED 8      /* the engine cannot do what was asked */

typedef int32_t pf_status;

/* Reductions of pf_dem_all_reduce (fixed numbers). */
#define PF_REDUCE_SUM 0
#define PF_REDUCE_MAX 1

/* The engine instance. */
typedef struct pf_dem pf_dem;

/* What the engine is and where it stands. */
typedef struct pf_dem_info {
    double time_step;      /* DEM time step, s */
    double time;           /* simulated time, s */
    uint64_t step_count;   /* steps taken */
    uint64_t particle_count; /* grains in the domain */
    uint64_t wall_count;   /* walls pf_dem_read_wall_forces reports */
    char name[32];         /* engine name, NUL-terminated ("native", "liggghts", "yade") */
    char version[96];      /* engine version, NUL-terminated */
} pf_dem_info;

/* Grains the engine fed and removed itself (inlets and outlets of the scene). */
typedef struct pf_dem_flow {
    uint64_t fed_count;      /* grains fed by the inlet */
    double fed_mass;         /* kg */
    uint64_t outflow_count;  /* grains that left through the outlet */
    double outflow_mass;     /* kg */
    uint64_t lost_count;     /* grains that left elsewhere */
} pf_dem_flow;

/* PF_DEM_ABI_MAJOR << 16 | PF_DEM_ABI_MINOR of the library. */
uint32_t pf_dem_abi_version(void);

/* Build an engine from the scene (the scene file as JSON text, `len` bytes, UTF-8).
 * On success *out holds the handle. On failure *out is NULL and
 * pf_dem_last_error(NULL, ...) tells why. */
pf_status pf_dem_create(const char *scene_json, size_t len, pf_dem **out);

/* Optional (1.1). Check the scene as pf_dem_create would (the engine's own refusals: its
 * mapping of laws, walls and grains) without starting the engine. On failure
 * pf_dem_last_error(NULL, ...) tells why. */
pf_status pf_dem_check(const char *scene_json, size_t len);

/* Free the engine; NULL is ignored. */
void pf_dem_destroy(pf_dem *dem);

/* Copy the last error message of `dem` (or, with NULL, of the last failed pf_dem_create on
 * this thread) into buf (NUL-terminated, truncated to len). Returns the message length
 * without the NUL, so a caller can size its buffer. */
size_t pf_dem_last_error(const pf_dem *dem, char *buf, size_t len);

/* Fill *info. */
pf_status pf_dem_info_get(const pf_dem *dem, pf_dem_info *info);

/* Advance `steps` DEM steps with the fluid forces held as last set. */
pf_status pf_dem_advance(pf_dem *dem, uint64_t steps);

/* Copy the grains into caller buffers of `capacity` grains (id: n; x, v, omega: 3 n;
 * radius, mass: n). Any buffer may be NULL to skip it. PF_ERR_BUFFER_TOO_SMALL when
 * capacity < particle_count. */
pf_status pf_dem_read_particles(const pf_dem *dem, size_t capacity, uint64_t *id, double *x,
                                double *v, double *omega, double *radius, double *mass);

/* Set the fluid force on every grain (3 n values, N), held until the next call. */
pf_status pf_dem_set_fluid_forces(pf_dem *dem, size_t n, const double *force);

/* Optional. Implicit drag: the engine adds coefficient_i (u_i - v_i) at every step, with
 * coefficient (n values, kg/s) and fluid velocity u (3 n values, m/s), on top of `force`
 * (3 n values, N; may be NULL for none). */
pf_status pf_dem_set_implicit_drag(pf_dem *dem, size_t n, const double *force,
                                   const double *coefficient, const double *fluid_velocity);

/* Insert n grains (x, v: 3 n; radius, density: n); the ids given go to ids_out (n; may be
 * NULL). PF_ERR_INVALID_ARGUMENT when a grain would overlap a wall or another grain badly
 * or lies outside the domain. */
pf_status pf_dem_insert(pf_dem *dem, size_t n, const double *x, const double *v,
                        const double *radius, const double *density, uint64_t *ids_out);

/* Remove grains past the outlet; their mass (kg) goes to *removed_mass (may be NULL). */
pf_status pf_dem_remove_past_outlet(pf_dem *dem, double *removed_mass);

/* Net force of the grains on each wall (3 wall_count values, N); names via
 * pf_dem_wall_name. PF_ERR_BUFFER_TOO_SMALL when capacity < wall_count. */
pf_status pf_dem_read_wall_forces(const pf_dem *dem, size_t capacity, double *force);

/* Name of wall `index` into buf (NUL-terminated, truncated to len). */
pf_status pf_dem_wall_name(const pf_dem *dem, size_t index, char *buf, size_t len);

/* Optional. The engine's own feed and outflow counters. */
pf_status pf_dem_flow_get(const pf_dem *dem, pf_dem_flow *flow);

/* Optional (ABI 1.2). Keep the engine's own log in folder `dir` (UTF-8, len bytes, no NUL
 * needed) when it closes, instead of deleting it with its working files. */
pf_status pf_dem_keep_log(pf_dem *dem, const char *dir, size_t len);

/* Optional (ABI 1.3). The engine's whole state between two calls of pf_dem_advance, as
 * bytes only this engine reads back (a checkpoint): *data points to *len bytes the engine
 * owns, valid until the next call on dem. An engine that cannot save its state answers
 * PF_ERR_UNSUPPORTED or PF_ERR_ENGINE with the reason. */
pf_status pf_dem_save_state(pf_dem *dem, const uint8_t **data, size_t *len);

/* Optional (ABI 1.3). Take back a state pf_dem_save_state wrote, on an engine created from
 * the same scene: the run goes on from there (grains, contact histories, the engine's own
 * feed and counters, its clock). PF_ERR_INVALID_ARGUMENT when the bytes are not such a
 * state. */
pf_status pf_dem_restore_state(pf_dem *dem, const uint8_t *data, size_t len);

/* Optional (ABI 1.4). This process's rank and the number of ranks the engine runs on
 * (0 and 1 for an engine in one process). */
pf_status pf_dem_ranks(const pf_dem *dem, uint32_t *rank, uint32_t *size);

/* Optional (ABI 1.4). Replace data[0..n) on every rank by its sum (op PF_REDUCE_SUM) or
 * maximum (PF_REDUCE_MAX) over all ranks. Collective: every rank calls it with the same n
 * and op. For a given rank count the result is the same at every call (a fixed reduction
 * order), so a run stays reproducible. */
pf_status pf_dem_all_reduce(const pf_dem *dem, double *data, size_t n, int32_t op);

#ifdef __cplusplus
}
#endif

#endif /* PLUGFLOW_DEM_H */
