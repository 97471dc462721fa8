# The emulated robot as its own host: EtherNet/IP target on TCP 44818 and UDP 2222, and the
# emulator's control API on TCP 8081 (docs/emulator.md). Built from the repository root:
#   docker build -f docker/emulator.Dockerfile .

# The wheels: the package's own, a cp311 platform wheel with the cyclic pump compiled by
# setuptools (gcc, libc's and Python's headers: the image has the latter), and its dependencies'.
FROM python:3.11-slim-bookworm AS wheel
ENV PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1
RUN apt-get update && apt-get install -y --no-install-recommends gcc libc6-dev \
    && rm -rf /var/lib/apt/lists/*
COPY backend/pyproject.toml backend/setup.py /src/backend/
COPY backend/src /src/backend/src
RUN pip wheel --wheel-dir /wheels /src/backend

FROM python:3.11-slim-bookworm

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1
WORKDIR /app
# The package from its platform wheel (stage "wheel": the cyclic pump compiled there, so this
# image has no compiler); COBOT_HMI_PUMP=native fails the build if the extension does not load.
COPY --from=wheel /wheels /wheels
RUN pip install --no-index --find-links /wheels cobot-hmi && rm -rf /wheels \
    && COBOT_HMI_PUMP=native python -m cobot_hmi.native \
    && useradd --system --no-create-home robot

USER robot
EXPOSE 44818/tcp 2222/udp 8081/tcp
# All addresses of the container: the control API's health check comes from inside it.
CMD ["cobot-hmi", "emulator", "--host", "0.0.0.0", "--control-port", "8081"]
