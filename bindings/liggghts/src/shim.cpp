// Thin C++ layer over LIGGGHTS's library interface (library.h). Its only job is to stop
// C++ exceptions at this boundary: every body catches everything and turns it into a status
// and a message. The plugflow DEM ABI itself is implemented in Rust (src/lib.rs) on top of
// these calls. Licence: GPL-2.0-or-later (links LIGGGHTS).
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <string>

#include <mpi.h>
#include <library.h>
// For the group bit only (pfl_group_bit): the library interface has no call for it.
#include <group.h>
#include <lammps.h>

namespace {
void put(char *err, size_t len, const char *what) {
    if (err == nullptr || len == 0) return;
    std::strncpy(err, what, len - 1);
    err[len - 1] = 0;
}
}  // namespace

#define PFL_GUARD(...)                                                        \
    try {                                                                     \
        __VA_ARGS__;                                                          \
        return 0;                                                             \
    } catch (const std::exception &e) {                                       \
        put(err, len, e.what());                                              \
        return 1;                                                             \
    } catch (...) {                                                           \
        put(err, len, "unknown C++ exception in LIGGGHTS");                   \
        return 1;                                                             \
    }

extern "C" {

// Open an instance without MPI, writing its log and screen output to files (LIGGGHTS
// crashes with `-screen none`).
int pfl_open(const char *log_path, const char *screen_path, void **out, char *err, size_t len) {
    PFL_GUARD({
        std::string log(log_path), screen(screen_path);
        const char *args[] = {"liggghts", "-log", log.c_str(), "-screen", screen.c_str(),
                              "-echo", "none"};
        *out = nullptr;
        lammps_open_no_mpi(7, const_cast<char **>(args), out);
        if (*out == nullptr) throw std::runtime_error("lammps_open_no_mpi returned no instance");
    })
}

// Under a launcher (mpirun): MPI initialised here if LIGGGHTS has not, this process's rank
// and the world's size.
int pfl_world(int *rank, int *size, char *err, size_t len) {
    PFL_GUARD({
        int ready = 0;
        MPI_Initialized(&ready);
        if (!ready) {
            int provided = 0;
            if (MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS)
                throw std::runtime_error("MPI_Init_thread failed");
        }
        MPI_Comm_rank(MPI_COMM_WORLD, rank);
        MPI_Comm_size(MPI_COMM_WORLD, size);
    })
}

// Open an instance over MPI_COMM_WORLD (one per rank, all ranks together); LIGGGHTS writes
// its log and screen from rank 0.
int pfl_open_world(const char *log_path, const char *screen_path, void **out, char *err,
                   size_t len) {
    PFL_GUARD({
        std::string log(log_path), screen(screen_path);
        const char *args[] = {"liggghts", "-log", log.c_str(), "-screen", screen.c_str(),
                              "-echo", "none"};
        *out = nullptr;
        lammps_open(7, const_cast<char **>(args), MPI_COMM_WORLD, out);
        if (*out == nullptr) throw std::runtime_error("lammps_open returned no instance");
    })
}

// In place over all ranks: op 0 sum, 1 maximum.
int pfl_all_reduce(double *data, size_t n, int op, char *err, size_t len) {
    PFL_GUARD({
        if (n > static_cast<size_t>(INT32_MAX)) throw std::runtime_error("buffer too long");
        int rc = MPI_Allreduce(MPI_IN_PLACE, data, static_cast<int>(n), MPI_DOUBLE,
                               op == 1 ? MPI_MAX : MPI_SUM, MPI_COMM_WORLD);
        if (rc != MPI_SUCCESS) throw std::runtime_error("MPI_Allreduce failed");
    })
}

// At the end of the process's last instance under a launcher.
int pfl_finalize(char *err, size_t len) {
    PFL_GUARD({
        int done = 0;
        MPI_Finalized(&done);
        if (!done) MPI_Finalize();
    })
}

int pfl_close(void *lmp, char *err, size_t len) { PFL_GUARD(lammps_close(lmp)) }

int pfl_command(void *lmp, const char *cmd, char *err, size_t len) {
    PFL_GUARD(lammps_command(lmp, cmd))
}

int pfl_natoms(void *lmp, int *out, char *err, size_t len) {
    PFL_GUARD(*out = lammps_get_natoms(lmp))
}

int pfl_extract_atom(void *lmp, const char *name, void **out, char *err, size_t len) {
    PFL_GUARD(*out = lammps_extract_atom(lmp, name))
}

int pfl_extract_global(void *lmp, const char *name, void **out, char *err, size_t len) {
    PFL_GUARD(*out = lammps_extract_global(lmp, name))
}

// Per-atom fix data: style 1 (per-atom), type 1 (vector) or 2 (array).
int pfl_extract_fix(void *lmp, const char *id, int type, void **out, char *err, size_t len) {
    PFL_GUARD(*out = lammps_extract_fix(lmp, id, 1, type, 0, 0))
}

// The one-bit mask of group `name` in the per-atom `mask` array, so that the caller can
// move atoms in and out of it without the `group` command (which cannot empty a group and
// makes LIGGGHTS set up again).
int pfl_group_bit(void *lmp, const char *name, int *out, char *err, size_t len) {
    PFL_GUARD({
        LAMMPS_NS::Group *g = static_cast<LAMMPS_NS::LAMMPS *>(lmp)->group;
        const int k = g->find(name);
        if (k < 0) throw std::runtime_error(std::string("no group `") + name + "`");
        *out = g->bitmask[k];
    })
}

}  // extern "C"
