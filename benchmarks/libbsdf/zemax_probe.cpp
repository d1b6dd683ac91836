// Reads a Zemax tabular BSDF with libbsdf (github.com/KimuraRyo/libbsdf, MPL 2.0) and answers queries on stdin,
// one a line: "f THETA_I X Y Z" prints the BRDF (sr^-1) for light at THETA_I degrees in the plane y = 0 (x > 0) and
// the outgoing unit vector (X, Y, Z); "a THETA_I" prints libbsdf's directional albedo there (its computeReflectance).
// Written for benchmarks/zemax_libbsdf.py (issue 37): an independent reader of `rig export --format zemax`.
#include <cmath>
#include <iostream>
#include <memory>
#include <string>

#include <libbsdf/Brdf/Analyzer.h>
#include <libbsdf/Common/Log.h>
#include <libbsdf/Reader/ZemaxBsdfReader.h>

int main(int argc, char** argv)
{
    if (argc != 2) {
        std::cerr << "usage: zemax_probe FILE.bsdf < queries\n";
        return 2;
    }
    lb::Log::setNotificationLevel(lb::Log::Level::WARN_MSG);      // its traces go to stdout, where the answers go
    lb::DataType type;
    std::unique_ptr<lb::SpecularCoordinatesBrdf> brdf(lb::ZemaxBsdfReader::read(argv[1], &type));
    if (!brdf || type != lb::BRDF_DATA) {
        std::cerr << "zemax_probe: " << argv[1] << ": libbsdf read no BRDF\n";
        return 1;
    }
    std::cout.precision(9);
    std::string kind;
    double theta_i;
    while (std::cin >> kind >> theta_i) {
        const double t = theta_i * M_PI / 180.0;
        const lb::Vec3 in(std::sin(t), 0.0, std::cos(t));
        if (kind == "a") {
            std::cout << lb::computeReflectance(*brdf, in)[0] << "\n";
            continue;
        }
        double x, y, z;
        std::cin >> x >> y >> z;
        std::cout << brdf->getValue(in, lb::Vec3(x, y, z), 0) << "\n";
    }
    return 0;
}
