// What a build and a trace share as jobs: progress, cancellation, and the
// errors that stop them.
#include <nanobind/nanobind.h>

#include <string>

#include "bindings/bindings.hpp"
#include "builders/memory.hpp"
#include "progress.hpp"

namespace bsp::bindings {

namespace nb = nanobind;
using namespace nb::literals;

void bind_jobs(nb::module_& m) {
    nb::exception<Cancelled>(m, "Cancelled", PyExc_RuntimeError);
    // Over memory_limit_mb: a MemoryError that says what the build needed.
    nb::register_exception_translator([](const std::exception_ptr& p, void*) {
        try {
            std::rethrow_exception(p);
        } catch (const MemoryLimitExceeded& e) {
            PyErr_SetString(PyExc_MemoryError, e.what());
        }
    });

    static const std::string hold_doc =
        "For tests: the work's n-th cancel check from now waits there until cancel() (at most " +
        std::to_string(Progress::kHoldLimit.count()) +
        " s), so that a cancel provably meets unfinished work.";
    nb::class_<Progress>(m, "Progress", "Progress of a build or trace; cancel() from any thread.")
        .def(nb::init<>())
        .def_prop_ro("value", &Progress::value, "Fraction done, 0..1.")
        .def_prop_ro("cancelled", &Progress::cancelled)
        .def("cancel", &Progress::cancel, "Ask the running work to stop.")
        .def("reset", &Progress::reset,
             "Ready for the next job: value back to 0 and any cancel cleared.")
        .def("hold_at_check", &Progress::hold_at_check, "n"_a, hold_doc.c_str())
        .def_prop_ro("held", &Progress::held,
                     "Whether the work has reached the check hold_at_check named.");
}

}  // namespace bsp::bindings
