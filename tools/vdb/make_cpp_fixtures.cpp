// Writes VDB fixtures that pyopenvdb cannot make (double and vec3d grids, zip and blosc
// without active-mask compression, rotated maps (OpenVDB stores the unitary and translation
// maps given here as AffineMap and UniformScaleTranslateMap), a frustum map, int32 and bool
// grids, an instanced grid) with real OpenVDB's C++ API, and prints OpenVDB's figures for every grid as JSON
// lines (the definitions of truth.jsonl).
//
// Build and run (needs Debian's libopenvdb-dev, libboost-dev and g++; CI does not need them:
// the outputs are committed in tests/data/vdb/cpp/):
//   g++ -O1 -std=c++17 make_cpp_fixtures.cpp -o /tmp/mk -lopenvdb -ltbb -lImath-3_1
//   /tmp/mk tests/data/vdb/cpp > tests/data/vdb/cpp/truth_cpp.jsonl
#include <openvdb/openvdb.h>
#include <openvdb/math/Maps.h>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

using namespace openvdb;

template <typename T> static double comp(const T& v, int k) { return double(v[k]); }
static double comp(double v, int) { return v; }
static double comp(float v, int) { return double(v); }

template <typename GridT>
static void printStats(const std::string& file, const GridT& g, int n) {
    double mn[3] = {INFINITY, INFINITY, INFINITY}, mx[3] = {-INFINITY, -INFINITY, -INFINITY};
    double sm[3] = {0, 0, 0}, mom[3] = {0, 0, 0};
    Index64 byDepth[4] = {0, 0, 0, 0};
    for (auto it = g.cbeginValueOn(); it; ++it) {
        CoordBBox bb;
        it.getBoundingBox(bb);
        double cnt = double(bb.volume());
        byDepth[it.getDepth()] += bb.volume();
        for (int k = 0; k < n; ++k) {
            double x = comp(*it, k);
            mn[k] = std::min(mn[k], x);
            mx[k] = std::max(mx[k], x);
            sm[k] += x * cnt;
            if (n == 1) {
                for (int a = 0; a < 3; ++a)
                    mom[a] += x * cnt * (bb.min()[a] + bb.max()[a]) / 2.0;
            }
        }
    }
    CoordBBox abb = g.evalActiveVoxelBoundingBox();
    auto p = [&](double x, double y, double z) {
        Vec3d w = g.transform().indexToWorld(Vec3d(x, y, z));
        char b[200];
        snprintf(b, sizeof b, "[%.17g, %.17g, %.17g]", w[0], w[1], w[2]);
        return std::string(b);
    };
    auto arr = [&](const double* v) {
        char b[200];
        if (n == 1) snprintf(b, sizeof b, "%.17g", v[0]);
        else snprintf(b, sizeof b, "[%.17g, %.17g, %.17g]", v[0], v[1], v[2]);
        return std::string(b);
    };
    double bg[3];
    for (int k = 0; k < n; ++k) bg[k] = comp(g.background(), k);
    printf("{\"file\": \"%s\", \"name\": \"%s\", \"type\": \"%s\", \"class\": \"%s\", "
           "\"map\": \"%s\", \"save_half\": %s, \"background\": %s, "
           "\"active_voxels\": %llu, \"active_voxels_by_depth\": [%llu, %llu, %llu, %llu], "
           "\"leaf_count\": %llu, \"active_bbox\": [[%d, %d, %d], [%d, %d, %d]], "
           "\"min\": %s, \"max\": %s, \"sum\": %s, \"moment\": [%.17g, %.17g, %.17g], "
           "\"index_to_world_origin\": %s, \"index_to_world_x1\": %s, "
           "\"index_to_world_y1\": %s, \"index_to_world_z1\": %s}\n",
           file.c_str(), g.getName().c_str(), g.valueType().c_str(),
           GridBase::gridClassToString(g.getGridClass()).c_str(),
           g.transform().mapType().c_str(), g.saveFloatAsHalf() ? "true" : "false", arr(bg).c_str(),
           (unsigned long long)g.activeVoxelCount(), (unsigned long long)byDepth[0],
           (unsigned long long)byDepth[1], (unsigned long long)byDepth[2],
           (unsigned long long)byDepth[3], (unsigned long long)g.tree().leafCount(),
           abb.min()[0], abb.min()[1], abb.min()[2], abb.max()[0], abb.max()[1], abb.max()[2],
           arr(mn).c_str(), arr(mx).c_str(), arr(sm).c_str(), mom[0], mom[1], mom[2],
           p(0, 0, 0).c_str(), p(1, 0, 0).c_str(), p(0, 1, 0).c_str(), p(0, 0, 1).c_str());
}

template <typename GridT, typename MakeV>
static typename GridT::Ptr makeGrid(const std::string& name, typename GridT::ValueType bg,
                                    MakeV makeV, std::mt19937& rng) {
    auto g = GridT::create(bg);
    g->setName(name);
    auto acc = g->getAccessor();
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int i = -6; i < 7; ++i)
        for (int j = -4; j < 6; ++j)
            for (int k = 0; k < 11; ++k) {
                Coord c(i, j, k);
                acc.setValue(c, makeV(u(rng)));
                if (u(rng) < 0.3) acc.setValueOff(c);
            }
    g->tree().addTile(1, Coord(8, 8, 512), makeV(0.25), true);  // 8^3 tile
    g->tree().addTile(2, Coord(256, 0, 0), makeV(0.5), true);   // 128^3 tile
    g->tree().addTile(3, Coord(4096, 0, 0), makeV(0.75), true); // root tile
    g->tree().addTile(2, Coord(0, 512, 0), makeV(2.0), false);  // inactive, not background
    return g;
}

int main(int argc, char** argv) {
    if (argc < 2) return 2;
    std::string out = argv[1];
    openvdb::initialize();
    std::mt19937 rng(5);
    Mat4d rot = Mat4d::identity();
    rot.setToRotation(Vec3d(1, 2, 3).unit(), 0.7);
    auto affine = math::Transform::createLinearTransform(0.2);
    affine->preRotate(0.3, math::Y_AXIS);
    affine->postTranslate(Vec3d(1, -2, 0.5));

    auto d = makeGrid<DoubleGrid>("temperature", 0.5, [](double x) { return x * 300.0; }, rng);
    d->setTransform(affine->copy());
    auto v = makeGrid<Vec3DGrid>("vel64", Vec3d(0, 0, 0),
                                 [](double x) { return Vec3d(x, -2 * x, x * x); }, rng);
    v->setTransform(math::Transform::Ptr(new math::Transform(
        math::MapBase::Ptr(new math::UnitaryMap(rot)))));
    auto f = makeGrid<FloatGrid>("density", 0.0f, [](double x) { return float(x); }, rng);
    f->setTransform(math::Transform::Ptr(new math::Transform(
        math::MapBase::Ptr(new math::TranslationMap(Vec3d(3, -1, 2))))));
    auto fv = makeGrid<Vec3SGrid>("velocity", Vec3s(0, 0, 0),
                                  [](double x) { return Vec3s(float(x), 1.0f, float(-x)); }, rng);
    fv->setTransform(affine->copy());

    // A grid sharing the tree of "density": OpenVDB writes it as an instance (no tree of its
    // own, only a reference to its parent's).
    auto inst = f->copyGrid();
    inst->setName("density_instance");
    inst->setTransform(math::Transform::createLinearTransform(0.5));

    struct Case { const char* name; uint32_t comp; bool half; };
    Case cases[] = {
        {"cpp_zip.vdb", io::COMPRESS_ZIP, false},
        {"cpp_blosc.vdb", io::COMPRESS_BLOSC, false},
        {"cpp_zip_mask.vdb", io::COMPRESS_ZIP | io::COMPRESS_ACTIVE_MASK, false},
        {"cpp_blosc_half.vdb", io::COMPRESS_BLOSC, true},
        {"cpp_zip_mask_half.vdb", io::COMPRESS_ZIP | io::COMPRESS_ACTIVE_MASK, true},
    };
    for (auto& c : cases) {
        for (auto g : {GridBase::Ptr(d), GridBase::Ptr(v), GridBase::Ptr(f), GridBase::Ptr(fv)})
            g->setSaveFloatAsHalf(c.half);
        io::File file(out + "/" + c.name);
        file.setCompression(c.comp);
        inst->setSaveFloatAsHalf(c.half);
        GridPtrVec grids{d, v, f, fv, inst};
        file.write(grids);
        file.close();
        // Read back with OpenVDB and print its figures.
        io::File in(out + "/" + c.name);
        in.open(false);
        for (auto name : {"temperature", "vel64", "density", "velocity", "density_instance"}) {
            GridBase::Ptr b = in.readGrid(name);
            if (auto g = gridPtrCast<DoubleGrid>(b)) printStats(c.name, *g, 1);
            if (auto g = gridPtrCast<Vec3DGrid>(b)) printStats(c.name, *g, 3);
            if (auto g = gridPtrCast<FloatGrid>(b)) printStats(c.name, *g, 1);
            if (auto g = gridPtrCast<Vec3SGrid>(b)) printStats(c.name, *g, 3);
        }
        in.close();
    }
    // Grids velour must refuse with a clear error.
    {
        auto i = Int32Grid::create(0);
        i->setName("labels");
        i->tree().setValue(Coord(1, 2, 3), 7);
        auto b = BoolGrid::create(false);
        b->setName("mask");
        b->tree().setValue(Coord(1, 2, 3), true);
        auto fr = FloatGrid::create(0.0f);
        fr->setName("frustum");
        fr->tree().setValue(Coord(1, 2, 3), 1.0f);
        fr->setTransform(math::Transform::createFrustumTransform(
            math::BBox<Vec3d>(Vec3d(0, 0, 0), Vec3d(10, 10, 10)), 0.5, 2.0, 1.0));
        io::File file(out + "/cpp_unsupported.vdb");
        file.write(GridPtrVec{i, b, fr});
        file.close();
    }
    return 0;
}
