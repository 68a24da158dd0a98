// The private extension module preisach._core: one register_<area>() per area.
#include "common.hpp"

PYBIND11_MODULE(_core, m) {
    m.doc() = "C++ core of preisach (private: use the preisach package).";
    register_everett(m);
    register_state(m);
    register_simulator(m);
    register_inverse(m);
    register_control(m);
    register_identify(m);
    register_diagnose(m);
    register_blocks(m);
    register_daq(m);
    register_rate(m);
}
