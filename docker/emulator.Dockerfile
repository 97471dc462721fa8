# The emulated robot as its own host: EtherNet/IP target on TCP 44818 and UDP 2222, and the
# emulator's control API on TCP 8081 (docs/emulator.md). Built from the repository root:
#   docker build -f docker/emulator.Dockerfile .
FROM python:3.11-slim-bookworm

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1
WORKDIR /app
COPY backend/pyproject.toml /app/backend/
COPY backend/src /app/backend/src
# The cyclic pump (cobot_hmi/native) is C: built here with gcc, which is removed again.
RUN apt-get update && apt-get install -y --no-install-recommends gcc libc6-dev \
    && pip install /app/backend \
    && python -m cobot_hmi.native \
    && apt-get purge -y gcc libc6-dev && apt-get autoremove -y && rm -rf /var/lib/apt/lists/* \
    && useradd --system --no-create-home robot

USER robot
EXPOSE 44818/tcp 2222/udp 8081/tcp
# All addresses of the container: the control API's health check comes from inside it.
CMD ["cobot-hmi", "emulator", "--host", "0.0.0.0", "--control-port", "8081"]
