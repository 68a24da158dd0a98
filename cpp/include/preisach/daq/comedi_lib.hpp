// ComedilibApi: the ComediApi of comedi.hpp on the real comedilib (only with
// PREISACH_HAVE_COMEDI, defined by CMake when comedilib.h and libcomedi are found).
#pragma once

#include <memory>
#include <string>

#include "comedi.hpp"

#ifdef PREISACH_HAVE_COMEDI
#include <comedilib.h>
#endif

namespace preisach::daq {

// Whether this build can talk to real Comedi hardware.
constexpr bool comedi_available() noexcept {
#ifdef PREISACH_HAVE_COMEDI
    return true;
#else
    return false;
#endif
}

#ifdef PREISACH_HAVE_COMEDI

class ComedilibApi final : public ComediApi {
public:
    ComedilibApi() { comedi_set_global_oor_behavior(COMEDI_OOR_NAN); }
    ~ComedilibApi() override {
        if (cal_) comedi_cleanup_calibration(cal_);
        if (dev_) comedi_close(dev_);
    }
    bool open(const std::string& file) override {
        dev_ = comedi_open(file.c_str());
        return dev_ != nullptr;
    }
    void close() override {
        if (dev_) comedi_close(dev_);
        dev_ = nullptr;
    }
    std::string error() override {
        const char* s = comedi_strerror(comedi_errno());
        return s ? s : "unknown comedilib error";
    }
    std::string board_name() override {
        const char* s = comedi_get_board_name(dev_);
        return s ? s : "?";
    }
    int find_subdevice_by_type(int type, unsigned start) override {
        return comedi_find_subdevice_by_type(dev_, type, start);
    }
    int get_subdevice_type(unsigned s) override { return comedi_get_subdevice_type(dev_, s); }
    int get_subdevice_flags(unsigned s) override { return comedi_get_subdevice_flags(dev_, s); }
    int get_n_channels(unsigned s) override { return comedi_get_n_channels(dev_, s); }
    long long get_maxdata(unsigned s, unsigned c) override { return (long long)comedi_get_maxdata(dev_, s, c); }
    int find_range(unsigned s, unsigned c, double lo, double hi) override {
        return comedi_find_range(dev_, s, c, UNIT_volt, lo, hi);
    }
    bool load_calibration(const std::string& path) override {
        std::string p = path;
        if (p.empty()) {
            char* d = comedi_get_default_calibration_path(dev_);
            if (!d) return false;
            p = d;
            std::free(d);
        }
        cal_ = comedi_parse_calibration_file(p.c_str());
        return cal_ != nullptr;
    }
    int softcal_converter(unsigned s, unsigned c, unsigned r, bool to, ComediPoly& p) override {
        comedi_polynomial_t poly{};
        const int rc = comedi_get_softcal_converter(s, c, r, to ? COMEDI_TO_PHYSICAL : COMEDI_FROM_PHYSICAL, cal_, &poly);
        if (rc >= 0) copy(poly, p);
        return rc;
    }
    int hardcal_converter(unsigned s, unsigned c, unsigned r, bool to, ComediPoly& p) override {
        comedi_polynomial_t poly{};
        const int rc = comedi_get_hardcal_converter(dev_, s, c, r, to ? COMEDI_TO_PHYSICAL : COMEDI_FROM_PHYSICAL, &poly);
        if (rc >= 0) copy(poly, p);
        return rc;
    }
    int data_read(unsigned s, unsigned c, unsigned r, unsigned a, unsigned& data) override {
        lsampl_t d = 0;
        const int rc = comedi_data_read(dev_, s, c, r, a, &d);
        data = d;
        return rc;
    }
    int data_write(unsigned s, unsigned c, unsigned r, unsigned a, unsigned data) override {
        return comedi_data_write(dev_, s, c, r, a, data);
    }
    double to_physical(unsigned data, const ComediPoly& p) override {
        const comedi_polynomial_t poly = to_c(p);
        return comedi_to_physical(data, &poly);
    }
    unsigned from_physical(double v, const ComediPoly& p) override {
        const comedi_polynomial_t poly = to_c(p);
        return comedi_from_physical(v, &poly);
    }

private:
    static void copy(const comedi_polynomial_t& c, ComediPoly& p) {
        for (int i = 0; i < 4; ++i) p.coefficients[i] = c.coefficients[i];
        p.expansion_origin = c.expansion_origin;
        p.order = c.order;
    }
    static comedi_polynomial_t to_c(const ComediPoly& p) {
        comedi_polynomial_t c{};
        for (int i = 0; i < 4; ++i) c.coefficients[i] = p.coefficients[i];
        c.expansion_origin = p.expansion_origin;
        c.order = p.order;
        return c;
    }
    comedi_t* dev_ = nullptr;
    comedi_calibration_t* cal_ = nullptr;
};

#endif

// The comedilib interface of this build: the real one, or an error naming what is missing.
inline std::unique_ptr<ComediApi> make_comedilib_api(const std::string& file) {
#ifdef PREISACH_HAVE_COMEDI
    (void)file;
    return std::make_unique<ComedilibApi>();
#else
    throw DeviceError("cannot open Comedi device '" + file +
                      "': this build of preisach has no Comedi support (comedilib was not found when it was "
                      "compiled; install libcomedi-dev and rebuild)");
#endif
}

}  // namespace preisach::daq
