// v4l2_capture_test.cpp - V4L2Capture against a fake driver behind the VideoSyscalls seam: format negotiation,
// buffer mapping, the DQBUF/QBUF cycle, YUYV and MJPEG frames, timeouts, unplugging, and clean-up.
#include "v4l2_capture.hpp"

#include <cerrno>
#include <cstring>
#include <deque>
#include <linux/videodev2.h>
#include <sys/mman.h>

#include <opencv2/imgcodecs.hpp>

#include <gtest/gtest.h>

using namespace rbx1::camera;

namespace {

constexpr int kFakeFd = 4242;

// One fake capture device: 640x480 at most, YUYV always, MJPEG when offered.
struct FakeDriver {
  bool exists = true, capture = true, offers_mjpeg = true, unplugged = false, stalled = false;
  uint32_t pixfmt = 0, width = 0, height = 0, bytesperline = 0;
  std::vector<std::vector<uint8_t>> buffers;
  std::deque<uint32_t> queued;
  bool streaming = false;
  int frames = 0, mapped = 0, streamoffs = 0, opens = 0, closes = 0;
  std::vector<uint8_t> jpeg;  // the MJPEG frame served

  void fill(uint32_t index, v4l2_buffer* b) {
    ++frames;
    std::vector<uint8_t>& buf = buffers[index];
    if (pixfmt == V4L2_PIX_FMT_YUYV) {
      // Gray level steps with the frame number: Y = 16 + 10 * frame, U = V = 128; padding bytes are 0xEE.
      std::fill(buf.begin(), buf.end(), 0xEE);
      uint8_t y = static_cast<uint8_t>(16 + 10 * frames);
      for (uint32_t r = 0; r < height; ++r)
        for (uint32_t x = 0; x < width * 2; x += 2) {
          buf[r * bytesperline + x] = y;
          buf[r * bytesperline + x + 1] = 128;
        }
      b->bytesused = bytesperline * height;
    } else {
      std::memcpy(buf.data(), jpeg.data(), jpeg.size());
      b->bytesused = static_cast<uint32_t>(jpeg.size());
    }
  }
};

FakeDriver* drv = nullptr;

int fake_open(const char* path, int) {
  if (!drv->exists || std::strcmp(path, "/dev/video-fake") != 0) {
    errno = ENOENT;
    return -1;
  }
  ++drv->opens;
  return kFakeFd;
}

int fake_close(int fd) {
  EXPECT_EQ(fd, kFakeFd);
  ++drv->closes;
  return 0;
}

int fail(int e) {
  errno = e;
  return -1;
}

int fake_ioctl(int fd, unsigned long request, void* arg) {
  if (fd != kFakeFd) return fail(EBADF);
  if (drv->unplugged) return fail(ENODEV);
  switch (request) {
    case VIDIOC_QUERYCAP: {
      auto* cap = static_cast<v4l2_capability*>(arg);
      std::memset(cap, 0, sizeof *cap);
      std::strcpy(reinterpret_cast<char*>(cap->card), "fake camera");
      cap->device_caps = (drv->capture ? V4L2_CAP_VIDEO_CAPTURE : V4L2_CAP_VIDEO_OUTPUT) | V4L2_CAP_STREAMING;
      cap->capabilities = cap->device_caps | V4L2_CAP_DEVICE_CAPS;
      return 0;
    }
    case VIDIOC_S_FMT: {
      auto* f = static_cast<v4l2_format*>(arg);
      if (f->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      uint32_t want = f->fmt.pix.pixelformat;
      drv->pixfmt = (want == V4L2_PIX_FMT_MJPEG && drv->offers_mjpeg) ? V4L2_PIX_FMT_MJPEG : V4L2_PIX_FMT_YUYV;
      drv->width = std::min<uint32_t>(f->fmt.pix.width, 640);
      drv->height = std::min<uint32_t>(f->fmt.pix.height, 480);
      drv->bytesperline = drv->pixfmt == V4L2_PIX_FMT_YUYV ? drv->width * 2 + 64 : 0;  // padded lines
      f->fmt.pix.pixelformat = drv->pixfmt;
      f->fmt.pix.width = drv->width;
      f->fmt.pix.height = drv->height;
      f->fmt.pix.bytesperline = drv->bytesperline;
      return 0;
    }
    case VIDIOC_S_PARM: {
      auto* p = static_cast<v4l2_streamparm*>(arg);
      p->parm.capture.timeperframe = {1, std::min<uint32_t>(p->parm.capture.timeperframe.denominator, 25)};
      return 0;
    }
    case VIDIOC_REQBUFS: {
      auto* r = static_cast<v4l2_requestbuffers*>(arg);
      if (r->memory != V4L2_MEMORY_MMAP) return fail(EINVAL);
      r->count = std::min<uint32_t>(r->count, 3);
      size_t size = drv->pixfmt == V4L2_PIX_FMT_YUYV ? size_t(drv->bytesperline) * drv->height : 256 * 1024;
      drv->buffers.assign(r->count, std::vector<uint8_t>(size));
      return 0;
    }
    case VIDIOC_QUERYBUF: {
      auto* b = static_cast<v4l2_buffer*>(arg);
      if (b->index >= drv->buffers.size()) return fail(EINVAL);
      b->length = static_cast<uint32_t>(drv->buffers[b->index].size());
      b->m.offset = b->index * 0x100000;
      return 0;
    }
    case VIDIOC_QBUF: {
      auto* b = static_cast<v4l2_buffer*>(arg);
      if (b->index >= drv->buffers.size()) return fail(EINVAL);
      for (uint32_t q : drv->queued)
        if (q == b->index) return fail(EINVAL);  // queued twice: a bug in the capture loop
      drv->queued.push_back(b->index);
      return 0;
    }
    case VIDIOC_DQBUF: {
      auto* b = static_cast<v4l2_buffer*>(arg);
      if (!drv->streaming || drv->queued.empty()) return fail(EAGAIN);
      b->index = drv->queued.front();
      drv->queued.pop_front();
      b->flags = 0;
      drv->fill(b->index, b);
      return 0;
    }
    case VIDIOC_STREAMON:
      drv->streaming = true;
      return 0;
    case VIDIOC_STREAMOFF:
      drv->streaming = false;
      ++drv->streamoffs;
      return 0;
    default:
      return fail(ENOTTY);
  }
}

void* fake_mmap(void*, size_t length, int, int, int fd, off_t offset) {
  size_t index = static_cast<size_t>(offset / 0x100000);
  if (fd != kFakeFd || index >= drv->buffers.size() || length != drv->buffers[index].size()) {
    errno = EINVAL;
    return MAP_FAILED;
  }
  ++drv->mapped;
  return drv->buffers[index].data();
}

int fake_munmap(void*, size_t) {
  --drv->mapped;
  return 0;
}

int fake_poll(pollfd* fds, nfds_t, int) {
  fds[0].revents = 0;
  if (drv->unplugged) fds[0].revents = POLLERR;
  else if (drv->stalled) return 0;  // as if the 2 s timeout passed
  else if (drv->streaming && !drv->queued.empty()) fds[0].revents = POLLIN;
  return fds[0].revents ? 1 : 0;
}

const VideoSyscalls kFake{fake_open, fake_close, fake_ioctl, fake_mmap, fake_munmap, fake_poll};

struct V4L2Fake : ::testing::Test {
  FakeDriver d;
  void SetUp() override { drv = &d; }
  void TearDown() override { drv = nullptr; }
};

}  // namespace

TEST_F(V4L2Fake, YuyvStreamsAndRequeuesEveryBuffer) {
  std::string error;
  {
    V4L2Capture cap(kFake);
    ASSERT_EQ(cap.open(CameraConfig{"/dev/video-fake", 640, 480, 30, "YUYV"}, error), 0) << error;
    EXPECT_EQ(d.queued.size(), 3u);  // all mapped buffers handed to the driver
    EXPECT_EQ(d.mapped, 3);
    EXPECT_TRUE(d.streaming);
    for (int i = 1; i <= 8; ++i) {  // more frames than buffers: each buffer goes back after use
      cv::Mat f;
      ASSERT_EQ(cap.read(f), 0) << "frame " << i;
      ASSERT_EQ(f.size(), cv::Size(640, 480));
      ASSERT_EQ(f.type(), CV_8UC3);
      int y = 16 + 10 * i;
      EXPECT_NEAR(f.at<cv::Vec3b>(479, 639)[1], 1.164 * (y - 16), 1.5) << "frame " << i;
    }
    EXPECT_EQ(d.frames, 8);
    EXPECT_EQ(cap.describe(), "/dev/video-fake (V4L2 YUYV 640x480 at 25 fps)");
  }
  EXPECT_EQ(d.streamoffs, 1);  // destructor: STREAMOFF, unmap, close
  EXPECT_EQ(d.mapped, 0);
  EXPECT_EQ(d.closes, 1);
}

TEST_F(V4L2Fake, DriverSizeIsUsedWhenItDiffers) {
  V4L2Capture cap(kFake);
  std::string error;
  ASSERT_EQ(cap.open(CameraConfig{"/dev/video-fake", 1280, 720, 30, "YUYV"}, error), 0) << error;
  cv::Mat f;
  ASSERT_EQ(cap.read(f), 0);
  EXPECT_EQ(f.size(), cv::Size(640, 480));
}

TEST_F(V4L2Fake, MjpegFramesAreDecoded) {
  cv::Mat src(480, 640, CV_8UC3, cv::Scalar(200, 40, 90));
  ASSERT_TRUE(cv::imencode(".jpg", src, d.jpeg));
  V4L2Capture cap(kFake);
  std::string error;
  ASSERT_EQ(cap.open(CameraConfig{"/dev/video-fake", 640, 480, 30, "MJPEG"}, error), 0) << error;
  for (int i = 0; i < 4; ++i) {
    cv::Mat f;
    ASSERT_EQ(cap.read(f), 0);
    ASSERT_EQ(f.size(), cv::Size(640, 480));
    cv::Vec3b p = f.at<cv::Vec3b>(100, 100);
    EXPECT_NEAR(p[0], 200, 4);
    EXPECT_NEAR(p[1], 40, 4);
    EXPECT_NEAR(p[2], 90, 4);
  }
  d.jpeg.assign(100, 0x33);  // a broken frame: reported, and the buffer still goes back
  cv::Mat f;
  EXPECT_EQ(cap.read(f), -EBADMSG);
  EXPECT_EQ(d.queued.size(), 3u);
}

TEST_F(V4L2Fake, RefusedFormatNamesWhatTheDriverChose) {
  d.offers_mjpeg = false;
  V4L2Capture cap(kFake);
  std::string error;
  EXPECT_EQ(cap.open(CameraConfig{"/dev/video-fake", 640, 480, 30, "MJPEG"}, error), -EINVAL);
  EXPECT_EQ(error, "/dev/video-fake: does not offer MJPEG (driver chose YUYV)");
  EXPECT_EQ(d.closes, 1);
}

TEST_F(V4L2Fake, NotACaptureDevice) {
  d.capture = false;
  V4L2Capture cap(kFake);
  std::string error;
  EXPECT_EQ(cap.open(CameraConfig{"/dev/video-fake"}, error), -ENODEV);
  EXPECT_EQ(error, "/dev/video-fake: not a video capture device");
}

TEST_F(V4L2Fake, MissingDevice) {
  d.exists = false;
  V4L2Capture cap(kFake);
  std::string error;
  EXPECT_EQ(cap.open(CameraConfig{"/dev/video-fake"}, error), -ENOENT);
  EXPECT_EQ(error, "/dev/video-fake: No such file or directory");
}

TEST_F(V4L2Fake, StallAndUnplugAreErrors) {
  V4L2Capture cap(kFake);
  std::string error;
  ASSERT_EQ(cap.open(CameraConfig{"/dev/video-fake", 320, 240, 30, "YUYV"}, error), 0) << error;
  cv::Mat f;
  ASSERT_EQ(cap.read(f), 0);
  d.stalled = true;
  EXPECT_EQ(cap.read(f), -ETIMEDOUT);
  d.stalled = false;
  d.unplugged = true;
  EXPECT_EQ(cap.read(f), -ENODEV);
}
