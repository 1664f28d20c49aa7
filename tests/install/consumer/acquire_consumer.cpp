// An installed msid::acquire from outside the tree: a device URI parsed, a bad one refused, and a
// device that is not there named in one msidacq::Error (nothing listens on port 1 of 127.0.0.1).
#include <msid_acquire.hpp>

#include <cstdio>
#include <cstring>

int main()
{
    const msidacq::DeviceUri d = msidacq::parse_device_uri("modbus-tcp://127.0.0.1:1?unit=3");
    if (d.port != 1 || d.unit != 3 || d.name() != "tcp:127.0.0.1:1") return 1;
    try {
        msidacq::parse_device_uri("127.0.0.1");
        return 2;
    } catch (const msidutil::UsageError &e) {
        if (!std::strstr(e.what(), "is not a device URI")) return 3;
    }
    struct Quiet : msidacq::Control {} ctl;
    try {
        msidacq::measure_device(d, [](uint32_t, msidacq::MeasurePlan &) {}, ctl);
        return 4;
    } catch (const msidacq::Error &e) {
        if (!std::strstr(e.what(), "127.0.0.1")) return 5;
        std::printf("acquire consumer: %s\n", e.what());
    }
    return 0;
}
