"""Run by Home Assistant's own python (tests/ha_live.py): print HA's entity registry and states as JSON.

    python ha_ws_dump.py ws://127.0.0.1:PORT/api/websocket TOKEN
"""

import asyncio
import json
import sys

import aiohttp  # HA's virtualenv has it; drivemap's test extra need not


async def main(url: str, token: str) -> None:
    async with aiohttp.ClientSession() as session, session.ws_connect(url, timeout=30) as ws:
        await ws.receive_json()  # auth_required
        await ws.send_json({"type": "auth", "access_token": token})
        answer = await ws.receive_json()
        if answer.get("type") != "auth_ok":
            raise SystemExit(f"auth refused: {answer}")
        out = {}
        for n, (key, kind) in enumerate((("registry", "config/entity_registry/list"), ("states", "get_states")), 1):
            await ws.send_json({"id": n, "type": kind})
            reply = await ws.receive_json()
            if not reply.get("success"):
                raise SystemExit(f"{kind} failed: {reply}")
            out[key] = reply["result"]
    print(json.dumps(out))


if __name__ == "__main__":
    asyncio.run(main(sys.argv[1], sys.argv[2]))
